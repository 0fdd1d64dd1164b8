"""The learned step on a whole batch as one flat graph (jraph-style node offsets).

The training step's default batches the learned step with ``jax.vmap`` over per-sample graphs
(:mod:`thrombojax.train.step`). :class:`FlatStep` runs the same step on ``[B, N, ...]`` arrays
with the model called *once*:

* per sample, as in :class:`~thrombojax.simulator.step.LearnedStep`: the inputs (in the step's
  frame, with its wall features) and the radius graph (``indices [N, K]``, sentinel ``N``);
* the node arrays are concatenated to ``[B*N, ...]`` and the neighbour indices offset by ``b*N``
  (sentinel slots become ``B*N``), :func:`flatten_graphs`, so the model sees one graph of
  ``B*N`` nodes whose components are the samples; its aggregation is then one ``segment_sum``
  (or slot sum) over ``[B*N, K]`` slots instead of a batched one;
* per sample again: denormalise, rotate back to the global frame, integrate.

Only a model whose every cross-node operation goes through its neighbour list gives the same
outputs this way: it must declare ``graph_local = True`` (MeshGraphNet does,
:class:`thrombojax.models.meshgraphnet.MeshGraphNetSurrogate`). Transolver's slice attention and
Erwin's ball tree mix every node of a sample, so they would mix samples too, and
:func:`flat_batch_ok` is False for them. The model is called with one dropout key for the whole
batch (a vmapped call gives each sample its own); MeshGraphNet has no dropout.

Equality with the vmapped step (loss and gradients): ``tests/test_flat_batch.py``; speed:
``benchmarks/flat_batch.py``.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from thrombojax.errors import ConfigError
from thrombojax.graph.neighbors import NeighborList, graph_overflow
from thrombojax.simulator.step import LearnedStep, StepOutput, integrate
from thrombojax.types import TargetStats

__all__ = ["FlatStep", "flat_batch_ok", "flatten_graphs"]


def flat_batch_ok(step: LearnedStep) -> bool:
    """Whether the step's surrogate gives the same outputs on a flat batch graph (and the step
    reads one previous frame: the flat step does not carry a history)."""
    return (bool(getattr(step.model, "graph_local", False)) and step.history == 1
            and not step.rest_edges and not step.start_speed)


def flatten_graphs(graphs: NeighborList) -> NeighborList:
    """One neighbour list of ``B*N`` nodes from ``B`` lists of ``N`` (batched ``[B, N, K]``).

    Sample ``b``'s node ``i`` becomes node ``b*N + i``; its neighbour indices are offset by
    ``b*N`` and its sentinel slots (``N``) become the flat sentinel ``B*N``, so no edge links two
    samples and padded slots stay padded. ``counts`` are concatenated; ``overflow`` is True if
    any sample's was.
    """
    b, n, k = graphs.indices.shape
    offsets = (jnp.arange(b, dtype=graphs.indices.dtype) * n)[:, None, None]
    indices = jnp.where(graphs.indices < n, graphs.indices + offsets, b * n)
    return NeighborList(indices=indices.reshape(b * n, k), counts=graphs.counts.reshape(b * n),
                        overflow=jnp.any(graphs.overflow))


@dataclasses.dataclass(frozen=True)
class FlatStep:
    """A :class:`LearnedStep` on a batch ``[B, N, ...]``, the model run once on the flat graph.

    Called like the learned step, with a leading batch axis on every array; returns a
    :class:`StepOutput` with ``positions``/``output`` ``[B, N, 3]`` and one ``overflow`` flag.
    Hashable (a static ``jit`` argument), and usable wherever a step is scanned over frames
    (:func:`thrombojax.simulator.rollout.unroll`).

    Attributes:
        step: the per-sample learned step; its surrogate must allow flat batches
            (:func:`flat_batch_ok`), else :class:`ConfigError`.
    """

    step: LearnedStep

    def __post_init__(self) -> None:
        if self.step.history != 1 or self.step.rest_edges or self.step.start_speed:
            raise ConfigError(f"the flat batch graph runs steps with one previous frame; this "
                              f"step reads history = {self.step.history}"
                              f"{' and the rest state' if self.step.rest_edges else ''}"
                              f"{' and the start frames' if self.step.start_speed else ''}: batch "
                              f"it with jax.vmap instead (flat_batch=False)")
        if not flat_batch_ok(self.step):
            raise ConfigError(f"model '{self.step.name}' mixes the nodes of a sample outside its "
                              f"neighbour list, so a flat batch graph would mix the samples; "
                              f"batch it with jax.vmap instead")

    @property
    def history(self) -> int:
        """Previous frames the step reads (always 1: see ``__post_init__``)."""
        return self.step.history

    def previous(self, positions, t, rest=None):
        """As :meth:`LearnedStep.previous` (``positions`` lead with the frame axis)."""
        return self.step.previous(positions, t, rest)

    def shift(self, x_prev: jax.Array, x_cur: jax.Array) -> jax.Array:
        """As :meth:`LearnedStep.shift`."""
        return self.step.shift(x_prev, x_cur)

    @property
    def name(self) -> str:
        """The surrogate's registry name."""
        return self.step.name

    def require_dense(self, what: str) -> None:
        """As :meth:`LearnedStep.require_dense`."""
        self.step.require_dense(what)

    def context(self, x: jax.Array, node_type: jax.Array, mask: jax.Array):
        """As :meth:`LearnedStep.context`, of every sample (leading batch axis ``[B, ...]``)."""
        return jax.vmap(self.step.context)(x, node_type, mask)

    def __call__(
        self,
        params: dict,
        stats: TargetStats,
        x_prev: jax.Array,
        x_cur: jax.Array,
        node_type: jax.Array,
        mask: jax.Array,
        *,
        train: bool = False,
        rng: jax.Array | None = None,
        context=None,
    ) -> StepOutput:
        """One step of every sample: ``x_prev, x_cur [B, N, 3]``, ``node_type, mask [B, N]``;
        ``context``: :meth:`context` (batched), or None.

        Returns: positions and outputs ``[B, N, 3]``, overflow ``[]`` (any sample's graph).
        """
        step = self.step
        b, n = mask.shape

        def prepare(p, c, t, m, ctx):
            inputs = step._inputs(step.frame_of(c, t, m), stats, p, c, t, m, ctx)
            return inputs, step.build_graph(inputs)

        inputs, graphs = jax.vmap(prepare)(x_prev, x_cur, node_type, mask, context)
        flat_inputs = jax.tree.map(lambda x: x.reshape((b * n,) + x.shape[2:]), inputs)
        out = step.model.apply(params, flat_inputs, flatten_graphs(graphs), train=train, rng=rng)
        out = out.reshape(b, n, -1)

        def finish(o, p, c, t, m, ctx):
            accel, o = step.accelerate(stats, o, step.frame_of(c, t, m), p, c, t, m, ctx)
            return integrate(p, c, accel, t, m), o

        positions, out = jax.vmap(finish)(out, x_prev, x_cur, node_type, mask, context)
        return StepOutput(positions=positions, output=out, overflow=graph_overflow(graphs))
