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
* Aggregation: sum (``jraph.segment_sum``) over incoming edges; the edge MLP input is
  ``[e_ij, v_sender, v_receiver]`` (PhysicsNeMo's order).
* Edge displacement sign: ``x_receiver - x_sender`` (= ``x_i - x_j`` in the thesis); DeepMind uses
  the opposite sign, which only flips the first encoder weights.
* Mesh and world edges are one edge set (as in the study and PhysicsNeMo).
* Graph layout: :func:`thrombojax.graph.neighbors.to_graphs_tuple` appends one zero dummy node
  that receives every sentinel edge, so padded slots never reach a real node and no edge mask
  is needed; padded (masked) nodes are in no neighbour list, so they never reach real nodes.
"""

from __future__ import annotations

import dataclasses

import flax.linen as nn
import jax
import jax.numpy as jnp
import jraph

from thrombojax.graph.neighbors import NeighborList, edge_displacements, to_graphs_tuple
from thrombojax.models.layers import MLP
from thrombojax.models.registry import FlaxSurrogate, MeshGraphNetConfig
from thrombojax.types import ModelInput

__all__ = ["MeshGraphNet", "MeshGraphNetSurrogate", "edge_features"]

OUTPUT_DIM: int = 3


def edge_features(positions: jax.Array, graph: NeighborList) -> jax.Array:
    """Edge input ``[n_nodes * K, 4]``: ``x_i - x_j`` and its norm (zeros on sentinel edges)."""
    dx, dist = edge_displacements(jax.lax.stop_gradient(positions), graph)
    return jnp.concatenate([dx, dist], axis=-1)


class MeshGraphNet(nn.Module):
    """The MeshGraphNet network on one sample.

    Attributes:
        config: :class:`~thrombojax.models.registry.MeshGraphNetConfig`.
    """

    config: MeshGraphNetConfig

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
        hidden = self.config.hidden
        n = inputs.n_nodes
        g: jraph.GraphsTuple = to_graphs_tuple(
            graph, inputs.node_features, edge_features(inputs.positions, graph)
        )
        nodes = self._mlp(hidden, norm=True, name="node_encoder")(g.nodes)  # [N+1, H]
        edges = self._mlp(hidden, norm=True, name="edge_encoder")(g.edges)  # [N*K, H]
        for b in range(self.config.processor_size):
            edge_in = jnp.concatenate([edges, nodes[g.senders], nodes[g.receivers]], axis=-1)
            edges = edges + self._mlp(hidden, norm=True, name=f"edge_block_{b}")(edge_in)
            agg = jraph.segment_sum(edges, g.receivers, num_segments=n + 1)
            node_in = jnp.concatenate([nodes, agg], axis=-1)
            nodes = nodes + self._mlp(hidden, norm=True, name=f"node_block_{b}")(node_in)
        return self._mlp(OUTPUT_DIM, norm=False, name="decoder")(nodes[:n])


@dataclasses.dataclass(frozen=True)
class MeshGraphNetSurrogate(FlaxSurrogate):
    """MeshGraphNet behind the common surrogate contract (radius graph without self loops)."""

    module_cls = MeshGraphNet
    self_loops = False
