"""MeshGraphNet (Pfaff et al. 2021) on jraph, as NVIDIA PhysicsNeMo builds it (the study's source).

Encode -> process -> decode on the radius graph of the current positions (edges ``j -> i`` for
``|x_i - x_j| < r``, at most ``max_neighbors`` nearest per node, no self loops):

    v_i  = MLP_v([velocity_i, one_hot(type_i)])            node encoder (no absolute position)
    e_ij = MLP_e([x_i - x_j, |x_i - x_j|])                 edge encoder (translation invariant)
    for each of the ``processor_size`` unshared blocks:
        e_ij <- e_ij + MLP_E([e_ij, v_j, v_i])             edge update (sender j, receiver i)
        v_i  <- v_i + MLP_N([v_i, sum_j e_ij])             node update on the *updated* edges
    out_i = MLP_d(v_i)                                     decoder -> [n_nodes, 3]

Conventions (where the references differ; we follow PhysicsNeMo, which the study used):

* Every MLP is ``Dense -> ReLU`` x ``mlp_layers`` then ``Dense``; all but the decoder end in a
  LayerNorm (eps 1e-5). ReLU is PhysicsNeMo's and DeepMind's default activation.
* Residual order: the edge update comes first and the node update aggregates the post-residual
  edge features (PhysicsNeMo ``MeshEdgeBlock`` -> ``MeshNodeBlock``); DeepMind's reference
  aggregates the edge MLP outputs before their residual.
* Aggregation: sum over incoming edges; the edge MLP input is ``[e_ij, v_sender, v_receiver]``
  (PhysicsNeMo's order).
* Edge displacement sign: ``x_receiver - x_sender`` (= ``x_i - x_j`` in the thesis); DeepMind uses
  the opposite sign, which only flips the first encoder weights.
* Mesh and world edges are one edge set (as in the study and PhysicsNeMo).
* Graph layout: :func:`thrombojax.graph.neighbors.to_graphs_tuple` appends one zero dummy node
  that receives every sentinel edge, so padded slots never reach a real node and no edge mask
  is needed; padded (masked) nodes are in no neighbour list, so they never reach real nodes.

How it is computed (same parameters and, on the real nodes, the same outputs and gradients as
the plain form: ``tests/test_mgn_fast.py``; speed: ``benchmarks/train_step.py``):

* Edges live in the neighbour list's ``[N, K, H]`` slots (edge ``i*K + s`` is slot ``s`` of row
  ``i``). The edge MLP's first layer is factorised, ``W [e, v_s, v_r] + b = W_e e + (W_s v)[s] +
  (W_r v)_i + b`` (:class:`thrombojax.models.layers.SplitDense` on the one ``dense_0`` kernel):
  the node projections are computed once per node and gathered (sender) or broadcast over the
  row (receiver), never a ``[N*K, 3H]`` concatenation (``factorised=False``: the plain form).
* Aggregation is jraph's ``segment_sum`` by default; ``slot_sum=True`` sums the ``K`` slots of
  each row instead (masked; the dummy node then aggregates zeros instead of the sentinel edges,
  which only ever feed sentinel edges). It measured slower in the training step on the CPU
  (``benchmarks/results/train_step_cpu.md``), so it is off by default.
* ``config.remat`` (on by default, measured no slower on the CPU, ``docs/performance.md``):
  every MLP but the decoder is rematerialised
  (:func:`thrombojax.models.layers.remat_call`): the backward pass recomputes its hidden layers
  instead of storing them, so a training step keeps about one ``[N, K, H]`` edge tensor per
  block instead of about ten, for about one more forward pass of compute (peaks:
  ``benchmarks/train_step.py``).
"""

from __future__ import annotations

import dataclasses

import flax.linen as nn
import jax
import jax.numpy as jnp
import jraph

from thrombojax.graph.neighbors import NeighborList, edge_displacements, to_graphs_tuple
from thrombojax.models.layers import MLP, SplitDense, mlp_tail, remat_call
from thrombojax.models.registry import FlaxSurrogate, MeshGraphNetConfig
from thrombojax.types import ModelInput

__all__ = ["EdgeMLP", "MeshGraphNet", "MeshGraphNetSurrogate", "edge_features"]

OUTPUT_DIM: int = 3


def edge_features(
    positions: jax.Array, graph: NeighborList, rest: jax.Array | None = None,
    clot: jax.Array | None = None,
) -> jax.Array:
    """Edge input ``[n_nodes * K, 4]``: ``x_i - x_j`` and its norm (zeros on sentinel edges).

    With ``rest [n_nodes, 3]`` (the rest state) and ``clot [n_nodes]`` (bool), ``[n_nodes * K,
    8]``: also the rest-state displacement ``r_i - r_j`` and its norm on clot-clot edges, zeros
    on the others (the vessel is rigid: its edges never change length).
    """
    dx, dist = edge_displacements(jax.lax.stop_gradient(positions), graph)
    if rest is None:
        return jnp.concatenate([dx, dist], axis=-1)
    n, clot = positions.shape[0], jnp.asarray(clot, bool)
    both = clot[:, None] & clot[jnp.minimum(graph.indices, n - 1)] & (graph.indices < n)
    r_dx, r_dist = edge_displacements(jax.lax.stop_gradient(rest), graph)
    return jnp.concatenate([dx, dist, jnp.where(both.reshape(-1, 1), jnp.concatenate(
        [r_dx, r_dist], axis=-1), 0.0)], axis=-1)


class EdgeMLP(nn.Module):
    """The edge MLP of one processor block on ``[e_ij, v_sender, v_receiver]``.

    Same parameters as ``MLP((hidden,) * layers + (hidden,), relu, layer_norm=True)`` on the
    concatenation; ``factorised`` computes the first layer per node (module docstring).

    Attributes:
        hidden: width of every layer. layers: hidden layers. factorised: see above.
    """

    hidden: int
    layers: int
    factorised: bool = True

    @nn.compact
    def __call__(
        self, edges: jax.Array, nodes: jax.Array, senders: jax.Array, receivers: jax.Array
    ) -> jax.Array:
        """Args: edges ``[N, K, H]``, nodes ``[N+1, H]`` (dummy last), senders ``[N, K]`` and
        receivers ``[N*K]`` (sentinel ``N``). Returns: ``[N, K, H]``."""
        n, k, _ = edges.shape
        widths = (self.hidden,) * (self.layers + 1)
        if self.factorised:
            first = SplitDense(self.hidden, bias_part=2, name="dense_0")
            p_edge, p_send, p_recv = first(edges, nodes, nodes[:n])
            x = p_edge + p_send[senders] + p_recv[:, None, :]
        else:
            flat = jnp.concatenate(
                [edges.reshape(n * k, -1), nodes[senders.reshape(-1)], nodes[receivers]], axis=-1
            )
            x = nn.Dense(self.hidden, name="dense_0")(flat).reshape(n, k, self.hidden)
        return mlp_tail(x, widths, jax.nn.relu, norm=True)


class MeshGraphNet(nn.Module):
    """The MeshGraphNet network on one sample.

    Attributes:
        config: :class:`~thrombojax.models.registry.MeshGraphNetConfig`.
        factorised: factorised first layer of the edge MLPs (module docstring).
        slot_sum: aggregate by a masked sum over the ``K`` slots (default: ``segment_sum``).
    """

    config: MeshGraphNetConfig
    factorised: bool = True
    slot_sum: bool = False

    def _mlp(self, out: int, *, norm: bool, name: str) -> MLP:
        widths = (self.config.hidden,) * self.config.mlp_layers + (out,)
        return MLP(widths, activation=jax.nn.relu, layer_norm=norm, name=name)

    @nn.compact
    def __call__(
        self, inputs: ModelInput, graph: NeighborList, *, train: bool = False
    ) -> jax.Array:
        """Predict the normalised acceleration.

        Args:
            inputs: positions, velocity ``[n_nodes, 3]``, node types and mask ``[n_nodes]``.
            graph: radius graph of ``inputs.positions`` (``indices [n_nodes, K]``).
            train: unused (no dropout); part of the common signature.
        Returns:
            ``[n_nodes, 3]``.
        """
        cfg, hidden = self.config, self.config.hidden
        n, k = graph.indices.shape
        g: jraph.GraphsTuple = to_graphs_tuple(
            graph, inputs.node_features,
            edge_features(inputs.positions, graph, inputs.rest, inputs.clot_mask),
        )
        def call(module, *args):
            return remat_call(module, *args) if cfg.remat else module(*args)

        nodes = call(self._mlp(hidden, norm=True, name="node_encoder"), g.nodes)  # [N+1, H]
        edges = call(self._mlp(hidden, norm=True, name="edge_encoder"), g.edges)  # [N*K, H]
        edges = edges.reshape(n, k, hidden)
        for b in range(cfg.processor_size):
            update = EdgeMLP(hidden, cfg.mlp_layers, self.factorised, name=f"edge_block_{b}")
            edges = edges + call(update, edges, nodes, graph.indices, g.receivers)
            if self.slot_sum:
                # a float 0/1 mask: a multiply keeps only [N, K, 1] for the backward pass,
                # where a jnp.where would keep its [N, K, H] broadcast mask and zeros
                valid = (graph.indices < n)[..., None].astype(jnp.float32)  # [N, K, 1]
                agg = jnp.sum(edges * valid, axis=1)  # [N, H]
                agg = jnp.concatenate([agg, jnp.zeros((1, hidden), agg.dtype)], axis=0)
            else:
                agg = jraph.segment_sum(edges.reshape(n * k, hidden), g.receivers, n + 1)
            node_in = jnp.concatenate([nodes, agg], axis=-1)
            nodes = nodes + call(self._mlp(hidden, norm=True, name=f"node_block_{b}"), node_in)
        return self._mlp(OUTPUT_DIM, norm=False, name="decoder")(nodes[:n])


@dataclasses.dataclass(frozen=True)
class MeshGraphNetSurrogate(FlaxSurrogate):
    """MeshGraphNet behind the common surrogate contract (radius graph without self loops).

    Graph-local (every node interaction is an edge of the radius graph), so a training batch can
    run as one flat graph (:mod:`thrombojax.simulator.flat`).
    """

    module_cls = MeshGraphNet
    self_loops = False
    graph_local = True
    rest_edges = True
