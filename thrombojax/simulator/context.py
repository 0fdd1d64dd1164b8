"""The rollout context of a learned step: what a rollout computes once for every step.

The vessel-axis inputs, the vessel-following prior and the lateral hold of
:class:`thrombojax.simulator.step.LearnedStep` start from the wall normals of the vessel
(:func:`thrombojax.graph.wall_nodes.local_wall_plane`), whose dense ``N x N`` nearest-node
search is most of a step's time at 2,048 nodes on a CPU (``docs/performance.md``). The vessel is
rigid, so the search's vessel rows, the only ones those normals read, are the same at every
step: a rollout makes the search once, from its first frame, and every step reads it::

    context = make_context(step, x0, node_type, mask)       # or step.context(x0, ...)
    step(params, stats, x_prev, x_cur, node_type, mask, context=context)   # same result

:func:`thrombojax.simulator.rollout.unroll` (and every rollout, ensemble and committee built on
its scan) does so; a single step without a context searches its own frame, as before.
"""

from __future__ import annotations

import jax
from flax import struct

from thrombojax.graph.vessel_axis import vessel_axis
from thrombojax.graph.wall_nodes import wall_patches

__all__ = ["StepContext", "make_context", "shared_axes"]


@struct.dataclass
class StepContext:
    """What a rollout computes once, from its first frame, for every step: the rigid vessel's
    wall search (:func:`thrombojax.graph.wall_nodes.wall_patches`) that the vessel-axis inputs,
    the prior and the lateral hold would otherwise repeat at every step (the ``N x N`` search,
    most of a step's time at 2,048 nodes on a CPU: ``docs/performance.md``).

    Made by :func:`make_context` (:meth:`thrombojax.simulator.step.LearnedStep.context`); a
    step given one returns what it returns without it as long as the vessel nodes stay where
    they were (a rollout copies them exactly).

    Attributes:
        global_patch: ``[N, k]`` search in global coordinates, for the prior, the lateral hold
            and the vessel-axis features of a step in the global frame; None when the step
            reads none of them.
        frame_patch: ``[N, k]`` search in the step's frame, for the vessel-axis features of a
            step in the vessel's frame; None otherwise. (One array per search: two arguments
            holding the same search would keep XLA from sharing the work done on it.)
    """

    global_patch: jax.Array | None = None
    frame_patch: jax.Array | None = None

    @property
    def input_patch(self) -> jax.Array | None:
        """The search in the coordinates of the model's inputs (the vessel-axis features)."""
        return self.global_patch if self.frame_patch is None else self.frame_patch


def make_context(step, x: jax.Array, node_type: jax.Array, mask: jax.Array) -> StepContext | None:
    """The :class:`StepContext` of ``step`` (a :class:`~thrombojax.simulator.step.LearnedStep`)
    for a rollout whose vessel is that of frame ``x`` (any frame of the simulation: the vessel
    does not move). Jittable.

    Returns:
        None when the step reads no vessel axis (no axis features, prior or lateral hold:
        nothing to save); else the searches it reads, in global coordinates and, for the axis
        features of a step in the vessel's frame, in that frame's.
    """
    if step.axis_radius <= 0 and step.prior_radius <= 0 and step.lateral_radius <= 0:
        return None
    in_frame = step.axis_radius > 0 and step.frame != "global"
    glob = (wall_patches(x, node_type, mask) if step.prior_radius > 0
            or step.lateral_radius > 0 or not in_frame else None)
    if not in_frame:
        return StepContext(global_patch=glob)
    frame = step.frame_of(x, node_type, mask)
    return StepContext(global_patch=glob,
                       frame_patch=wall_patches(frame.points(x), node_type, mask))


def shared_axes(x: jax.Array, node_type: jax.Array, mask: jax.Array,
                context: StepContext | None, *, inputs: bool = False):
    """``radius -> vessel_axis(x, ..., radius=radius, patch=...)``, each width computed once;
    the patch is the context's search for the inputs' coordinates (``inputs``) or the global
    one, or none (``context`` None: the axis searches ``x``).

    A step's inputs, prior and lateral hold read the same axis; XLA merges the repeated
    computation in one step but not inside a rollout's loop, where its LAPACK ``eigh`` calls ran
    twice (measured: 12 ms more per step at 2,048 nodes on this CPU), so the step shares it."""
    patch = None if context is None else (context.input_patch if inputs else context.global_patch)
    memo: dict[float, jax.Array] = {}

    def axis(radius: float) -> jax.Array:
        if radius not in memo:
            memo[radius] = vessel_axis(x, node_type, mask, radius=radius, patch=patch)
        return memo[radius]

    return axis
