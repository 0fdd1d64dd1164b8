"""The one learned step: inputs -> graph -> model -> denormalise -> integrate.

Every consumer (the single-step and k-step training losses, the ``lax.scan`` rollout, evaluation,
the speed benchmark) calls the :class:`LearnedStep` made by :func:`make_step`; nothing else in the
package writes this sequence but :class:`thrombojax.simulator.flat.FlatStep`, the same step on a
whole batch run as one flat graph (tested equal: ``tests/test_flat_batch.py``). In the manner
of jax-md's ``simulate`` factories the factory fixes the static part (the surrogate) and returns
pure functions of arrays::

    step = make_step(model)
    params = step.init(rng, x_prev, x_cur, node_type, mask)
    out = step(params, stats, x_prev, x_cur, node_type, mask)     # StepOutput
    out.positions                                                  # s_{t+1}

The step, in scaled [-1, 1] coordinates::

    inputs  = (s_t, v_t / velocity_std, node type, mask),  v_t = s_t - s_{t-1}
    out     = model(inputs, graph built from s_t)          # normalised acceleration
    a_t     = out * std + mean                             # TargetStats of the training split
    s_{t+1} = s_t + v_t + a_t  for real clot nodes;  s_t for vessel and padded nodes (rigid)

:class:`LearnedStep` is a frozen, hashable dataclass, so it is a static argument of ``jax.jit``
(one compilation per surrogate and shapes). Called outside a trace, the step runs as one compiled
program (op by op, every operation would compile on its own: ~100 small programs for the tiny
MeshGraphNet); inside ``jit``, ``grad``, ``vmap`` or ``scan`` it is inlined into the caller's.

Frames: ``make_step(model, frame="vessel")`` runs the model in the frame of the rigid vessel
(:func:`thrombojax.graph.frame.vessel_frame`): positions and velocities enter in that frame's
coordinates and the acceleration is rotated back: invariant to the vessel's orientation up to
rounding (unseen rotations included; wall searches rank ties by ``wall_nodes.tie_key``). ``stats``
are statistics of the acceleration in that frame (``compute_target_stats(..., frame="vessel")``),
and :meth:`LearnedStep.normalized_target` is what the training loss compares ``output`` with.

Wall features: ``make_step(model, wall_cutoff=c)`` (``c > 0``, scaled units) appends to every
clot node's input the distance and direction to its nearest vessel node
(:func:`thrombojax.graph.wall_nodes.wall_node_features`), so the model knows where the wall is
even when no vessel node is among its graph neighbours; ``make_step(model, wall_cutoff=c,
wall_signed=True)`` gives instead the signed distance to the wall and its outward normal
(:func:`thrombojax.graph.wall_nodes.signed_wall_features`), which tell a node that crossed the
wall from one inside it; ``wall_clot_mean=True`` adds their clot-wide mean distance
(:func:`thrombojax.graph.wall_nodes.clot_wall_mean`: the room the whole clot has). The other
extra inputs, and their order: :mod:`thrombojax.simulator.features`.

History: ``make_step(model, history=H)`` (``H >= 2``) also gives the model the accelerations of the
``H - 1`` steps before t, ``a_{t-j} = s_{t-j+1} - 2 s_{t-j} + s_{t-j-1}`` (in the step's frame,
divided by one number, the RMS of ``stats.std``), as extra node features: state the current
velocity does not show (why: ``docs/rollouts.md``). ``x_prev`` is then ``[H, n_nodes, 3]``, the
frames ``s_{t-H} .. s_{t-1}`` oldest first (:meth:`LearnedStep.previous` takes them from a
trajectory, :meth:`LearnedStep.shift` advances them in a rollout); ``H = 1`` keeps ``x_prev``
``[n_nodes, 3]`` = s_{t-1}. ``make_step(model, rest_edges=True)`` also reads the clot's rest
state, the simulation's first frame, at the head of ``x_prev``
(:mod:`thrombojax.simulator.previous`), and MeshGraphNet's clot-clot edges get their rest-state
displacement beside the current one (DeepMind's deforming-plate model). ``start_speed=K``:
also the clot's start speed over K frames (:mod:`thrombojax.simulator.start_speed`).

Prior: ``make_step(model, prior_radius=w)`` adds the vessel-following prior to constant
velocity, and the model learns the rest (:mod:`thrombojax.simulator.step_options`).

Rollout context: the vessel is rigid, so ``step.context(x0, node_type, mask)`` searches its wall
once (:mod:`thrombojax.simulator.context`) and every rollout's ``step(..., context=...)`` reads it.

Full resolution: ``make_step(model, grid=spec)`` carries a static cell-grid
:class:`~thrombojax.graph.grid.GridSpec` to the model's radius search (where it pays,
:func:`thrombojax.graph.neighbors.radius_graph`); :attr:`StepOutput.overflow` reports a grid
buffer that was too small (:mod:`thrombojax.simulator.grid_step`).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from thrombojax.errors import ConfigError
from thrombojax.graph.frame import VesselFrame, vessel_frame
from thrombojax.graph.grid import GridSpec
from thrombojax.graph.neighbors import graph_overflow
from thrombojax.graph.vessel_axis import clot_lateral_mean
from thrombojax.models.registry import Surrogate
from thrombojax.simulator import previous as prev
from thrombojax.simulator.context import StepContext, make_context, shared_axes
from thrombojax.simulator.features import extra_features
from thrombojax.simulator.kinematics import (
    integrate,
    make_input,
    past_accelerations,
    target_acceleration,
)
from thrombojax.simulator.step_options import check_step_options, step_prior
from thrombojax.types import ModelInput, TargetStats

__all__ = ["StepOutput", "StepContext", "LearnedStep", "make_step", "make_input",
           "target_acceleration", "integrate", "past_accelerations"]


@struct.dataclass
class StepOutput:
    """What one learned step returns.

    Attributes:
        positions: ``[n_nodes, 3]`` s_{t+1} (vessel and padded nodes equal s_t exactly).
        output: ``[n_nodes, 3]`` the model output (normalised acceleration; with the lateral
            hold, the acceleration applied, normalised), what the training loss compares with
            the normalised target.
        overflow: ``[]`` bool, True if a cell-grid buffer of the graph overflowed (the graph,
            hence the step, may be wrong: re-allocate); always False without a grid.
    """

    positions: jax.Array
    output: jax.Array
    overflow: jax.Array


@dataclasses.dataclass(frozen=True)
class LearnedStep:
    """The learned simulator of one surrogate: pure functions of (params, stats, frames).

    Build it with :func:`make_step`. Hashable (the surrogate is a frozen dataclass), so it can
    be a static argument of ``jax.jit``.

    Attributes:
        model: the surrogate (:func:`thrombojax.models.create_model`).
        frame: ``"global"`` (the dataset's axes) or ``"vessel"`` (the rigid vessel's frame,
            see the module docstring).
        wall_cutoff: cutoff of the wall features in scaled units (0: no wall features).
        wall_signed: the wall features are the signed distance to the wall and its outward
            normal (:func:`thrombojax.graph.wall_nodes.signed_wall_features`), not the distance
            and direction to the nearest vessel node.
        wall_clot_mean: the clot nodes also get the clot-wide mean of the wall distance feature.
        grid: cell grid of the model's radius graph, in the step's frame (None: dense search).
        history: frames before t the step reads (1: s_{t-1}, the velocity alone; H >= 2: also
            the H - 1 accelerations before t, see the module docstring).
        stop_history_gradient: the history features are constants to differentiation (an
            unrolled loss then takes gradients through positions and velocities only, as for
            one velocity); outputs are unchanged.
        axis_radius: width in scaled units of the vessel-axis features, the velocity split
            along and across the local vessel axis
            (:func:`thrombojax.graph.vessel_axis.axis_velocity_features`; 0: none).
        prior_radius: > 0: the step's prior is the velocity turned onto the vessel's axis
            (:func:`thrombojax.graph.vessel_axis.follow_axis_offset`, this axis width, scaled)
            and the model learns the rest; 0: the prior is constant velocity.
        lateral_radius: > 0: the lateral hold, the clot-wide mean of the model's acceleration
            across the local vessel axis (this width, scaled) is taken out
            (:func:`thrombojax.graph.vessel_axis.clot_lateral_mean`) before the prior is added;
            ``StepOutput.output`` is then the acceleration the step applied, normalised. 0: off.
        outlet_radius: > 0: clot nodes also get where the clot is against the vessel's open
            ends, ahead of its motion (:func:`thrombojax.graph.vessel_axis.outlet_features`,
            this width, scaled); 0: off.
        shape_radius: > 0: clot nodes also get their place along the clot's motion and the
            clot's length and width (:func:`thrombojax.graph.clot_shape.clot_shape_features`,
            over this length, scaled); 0: off. (The order of all extra features:
            :mod:`thrombojax.simulator.features`.)
        clearance_radius, section_radius: > 0: clot nodes also get the clot's clearance
            (:func:`thrombojax.graph.clearance.clot_clearance`) / the vessel's width at the
            clot (:func:`thrombojax.graph.section.clot_section_features`) over this length,
            scaled; 0: off.
        centre_pull, centre_unit, centre_tolerance: with the prior, a share in (0, 1] of the
            clot centroid's offset from the cross-section's middle beyond ``centre_tolerance``
            (scaled) that the prior's velocities tilt back per step at their speed
            (:func:`thrombojax.graph.section.centre_pull`, a vessel radius ``centre_unit``,
            scaled); 0: off.
        rest_edges: the step also reads the clot's rest state (``x_prev`` led by the
            simulation's first frame, :mod:`thrombojax.simulator.previous`) and the model's
            edges get their rest-state displacement (a model that reads edge features only).
        start_speed: K >= 1 (``True``: 1): the step also reads the clot's mean speed over the K
            frames up to a rollout's start (:mod:`thrombojax.simulator.start_speed`); 0: off.
    """

    model: Surrogate
    frame: str = "global"
    wall_cutoff: float = 0.0
    wall_signed: bool = False
    wall_clot_mean: bool = False
    grid: GridSpec | None = None
    history: int = 1
    stop_history_gradient: bool = False
    axis_radius: float = 0.0
    prior_radius: float = 0.0
    lateral_radius: float = 0.0
    outlet_radius: float = 0.0
    shape_radius: float = 0.0
    rest_edges: bool = False
    clearance_radius: float = 0.0
    section_radius: float = 0.0
    centre_pull: float = 0.0
    centre_unit: float = 0.0
    centre_tolerance: float = 0.0
    start_speed: int = 0

    def __post_init__(self) -> None:
        check_step_options(self)

    def previous(self, positions, t, rest=None, start_from=None):
        """The ``x_prev`` of frame(s) ``t >= 1`` (int or int array) of a trajectory ``positions
        [T, n_nodes, 3]`` (:func:`thrombojax.simulator.previous.previous`; ``rest``: the lead
        frames when ``positions`` does not start at the simulation's first frame;
        ``start_from``: the start speed of frame ``min(t, start_from)``, None: of ``t``)."""
        return prev.previous(self.history, self.rest_edges, positions, t, rest,
                             start_speed=self.start_speed, start_from=start_from)

    def last_previous(self, x_prev: jax.Array) -> jax.Array:
        """s_{t-1} of an ``x_prev`` (see :meth:`previous`)."""
        return prev.last_previous(self.history, self.rest_edges, x_prev, self.start_speed)

    def shift(self, x_prev: jax.Array, x_cur: jax.Array) -> jax.Array:
        """The ``x_prev`` of the next step: the lead frames kept, the last H frames moved on."""
        return prev.shift(self.history, self.rest_edges, x_prev, x_cur, self.start_speed)

    def check_previous(self, x_prev, n_nodes: int, what: str) -> None:
        """Raise :class:`ConfigError` if ``x_prev`` does not have this step's history shape."""
        want = prev.previous_shape(self.history, self.rest_edges, n_nodes, self.start_speed)
        if tuple(np.shape(x_prev)) != want:
            rest = (" and the rest frame" if self.rest_edges else "") + (
                " and the start frames" if self.start_speed else "")
            raise ConfigError(f"{what}: the step reads {self.history} previous frame(s){rest}, "
                              f"so x_prev must be {want}, got {tuple(np.shape(x_prev))}")

    @property
    def name(self) -> str:
        """The surrogate's registry name."""
        return self.model.name

    def with_grid(self, grid: GridSpec | None) -> LearnedStep:
        """The same step with another cell grid (None: the dense search)."""
        return dataclasses.replace(self, grid=grid)

    def require_dense(self, what: str) -> None:
        """Raise :class:`ConfigError` if the step has a grid: ``what`` drops the overflow flag."""
        if self.grid is not None:
            raise ConfigError(f"{what} does not check the cell grid's overflow flag; use a "
                              f"step without a grid (step.with_grid(None)), or the checked "
                              f"rollout (thrombojax.simulator.rollout.rollout)")

    def build_graph(self, inputs: ModelInput):
        """The model's graph of ``inputs``, on the cell grid where the step has one and it pays."""
        if self.grid is None:  # surrogates written before the grid keep their one-argument call
            return self.model.build_graph(inputs)
        return self.model.build_graph(inputs, grid=self.grid)

    def frame_of(
        self, x_cur: jax.Array, node_type: jax.Array, mask: jax.Array
    ) -> VesselFrame | None:
        """The frame the model works in (None: the global frame, nothing is transformed)."""
        return None if self.frame == "global" else vessel_frame(x_cur, node_type, mask)

    def context(
        self, x: jax.Array, node_type: jax.Array, mask: jax.Array
    ) -> StepContext | None:
        """:func:`~thrombojax.simulator.context.make_context`: the context of a rollout on the
        vessel of frame ``x``; None when the step reads no vessel axis."""
        return make_context(self, x, node_type, mask)

    def inputs(
        self, stats: TargetStats, x_prev: jax.Array, x_cur: jax.Array, node_type: jax.Array,
        mask: jax.Array, *, context: StepContext | None = None,
    ) -> ModelInput:
        """The model input of frame t (velocity normalised by ``stats.velocity_std``), in the
        step's frame, with the wall features when the step has them (``context``: see
        :meth:`__call__`)."""
        frame = self.frame_of(x_cur, node_type, mask)
        return self._inputs(frame, stats, x_prev, x_cur, node_type, mask, context)

    def _inputs(self, frame, stats, x_prev, x_cur, node_type, mask, context=None,
                axes=None) -> ModelInput:
        """``stats`` None (initialisation): unit scales. ``axes``: ``shared_axes`` of ``x_cur``
        in global coordinates (read only when the step works in them)."""
        if frame is not None:
            x_prev, x_cur = frame.points(x_prev), frame.points(x_cur)
        if axes is None or frame is not None:
            axes = shared_axes(x_cur, node_type, mask, context, inputs=True)
        velocity_scale = 1.0 if stats is None else stats.velocity_std
        inputs = make_input(self.last_previous(x_prev), x_cur, node_type, mask, velocity_scale)
        extra = extra_features(self, stats, x_prev, x_cur, node_type, mask, velocity_scale, axes)
        return inputs.replace(extra=extra, rest=prev.rest_frame(self.rest_edges, x_prev))

    def prior(self, x_last, x_cur, node_type, mask, *, context: StepContext | None = None,
              axis: jax.Array | None = None) -> jax.Array | float:
        """What the step adds to constant velocity before the model's acceleration: the
        vessel-following offset (``prior_radius > 0``) or 0; ``x_last`` is s_{t-1}; ``axis``:
        the vessel axis of ``x_cur`` at ``prior_radius`` if computed before."""
        return step_prior(self, x_last, x_cur, node_type, mask, context, axis)

    def accelerate(self, stats, out, frame, x_prev, x_cur, node_type, mask, context=None,
                   axes=None):
        """The model's output ``out`` to the global acceleration the step applies (the lateral
        hold, then the prior added) and the output the training loss compares: ``out`` itself,
        or with the lateral hold the held acceleration in the step's frame, normalised.
        ``axes``: :func:`~thrombojax.simulator.context.shared_axes` of ``x_cur``, shared with
        the inputs (None: made here)."""
        accel = stats.denormalize(out)
        if frame is not None:
            accel = frame.vectors_to_global(accel)
        if axes is None:
            axes = shared_axes(x_cur, node_type, mask, context)
        if self.lateral_radius > 0:
            accel = accel - clot_lateral_mean(accel, x_cur, node_type, mask,
                                              radius=self.lateral_radius,
                                              axis=axes(self.lateral_radius))
            out = stats.normalize(accel if frame is None else frame.vectors(accel))
        prior = (0.0 if self.prior_radius <= 0 else
                 self.prior(self.last_previous(x_prev), x_cur, node_type, mask,
                            axis=axes(self.prior_radius)))
        return accel + prior, out

    def normalized_target(
        self, stats: TargetStats, accel: jax.Array, x_ref: jax.Array, node_type: jax.Array,
        mask: jax.Array,
    ) -> jax.Array:
        """What ``StepOutput.output`` should be: ``stats.normalize`` of the global acceleration
        ``accel [..., n_nodes, 3]`` expressed in the step's frame (taken from ``x_ref``, any
        frame of the simulation: the vessel does not move)."""
        frame = self.frame_of(x_ref, node_type, mask)
        return stats.normalize(accel if frame is None else frame.vectors(accel))

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
        context: StepContext | None = None,
    ) -> StepOutput:
        """One step s_{t-1}, s_t -> s_{t+1} (see the module docstring).

        Args:
            params: the surrogate's variables. stats: normalisation statistics.
            x_prev, x_cur: ``[n_nodes, 3]`` scaled positions s_{t-1}, s_t.
            node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
            train: training mode (dropout). rng: PRNG key of the dropout stream.
            context: :meth:`context` of a frame with the same vessel nodes (a rollout's
                first): the vessel's wall search is read from it instead of repeated; the
                result is the same. None: everything from this frame.
        Returns:
            The :class:`StepOutput`.
        """
        return _call(self, params, stats, x_prev, x_cur, node_type, mask, train, rng, context)

    def _apply(self, params, stats, x_prev, x_cur, node_type, mask, train, rng, context):
        frame = self.frame_of(x_cur, node_type, mask)
        axes = shared_axes(x_cur, node_type, mask, context)
        inputs = self._inputs(frame, stats, x_prev, x_cur, node_type, mask, context, axes)
        graph = self.build_graph(inputs)
        out = self.model.apply(params, inputs, graph, train=train, rng=rng)
        accel, out = self.accelerate(stats, out, frame, x_prev, x_cur, node_type, mask, context,
                                     axes)
        x_next = integrate(self.last_previous(x_prev), x_cur, accel, node_type, mask)
        return StepOutput(positions=x_next, output=out, overflow=graph_overflow(graph))

    def init(
        self, rng: jax.Array, x_prev: jax.Array, x_cur: jax.Array, node_type: jax.Array,
        mask: jax.Array,
    ) -> dict:
        """Initialise the surrogate's variables on one frame (compiled once per shape)."""
        return _init(self, rng, jnp.asarray(x_prev, jnp.float32), jnp.asarray(x_cur, jnp.float32),
                     jnp.asarray(node_type, jnp.int32), jnp.asarray(mask, bool))


@functools.partial(jax.jit, static_argnums=(0, 7), inline=True)
def _call(step: LearnedStep, *args) -> StepOutput:
    return step._apply(*args)


@functools.partial(jax.jit, static_argnums=0)
def _init(step: LearnedStep, rng, x_prev, x_cur, node_type, mask) -> dict:
    inputs = step._inputs(step.frame_of(x_cur, node_type, mask), None, x_prev, x_cur, node_type,
                          mask)
    return step.model.init(rng, inputs, step.build_graph(inputs))


def make_step(model: Surrogate, frame: str = "global", wall_cutoff: float = 0.0,
              grid: GridSpec | None = None, history: int = 1,
              stop_history_gradient: bool = False, wall_signed: bool = False,
              axis_radius: float = 0.0, prior_radius: float = 0.0,
              lateral_radius: float = 0.0, wall_clot_mean: bool = False,
              outlet_radius: float = 0.0, shape_radius: float = 0.0,
              rest_edges: bool = False, clearance_radius: float = 0.0,
              section_radius: float = 0.0, centre_pull: float = 0.0,
              centre_unit: float = 0.0, centre_tolerance: float = 0.0,
              start_speed: int = 0) -> LearnedStep:
    """The learned simulator of a surrogate in ``frame`` with the options of
    :class:`LearnedStep` (the radii are scaled lengths, 0: off; see the module docstring)."""
    return LearnedStep(model=model, frame=frame, grid=grid, history=history,
                       stop_history_gradient=bool(stop_history_gradient),
                       wall_signed=bool(wall_signed), wall_clot_mean=bool(wall_clot_mean),
                       rest_edges=bool(rest_edges), wall_cutoff=float(wall_cutoff),
                       axis_radius=float(axis_radius), prior_radius=float(prior_radius),
                       lateral_radius=float(lateral_radius), outlet_radius=float(outlet_radius),
                       shape_radius=float(shape_radius), clearance_radius=float(clearance_radius),
                       section_radius=float(section_radius), centre_pull=float(centre_pull),
                       centre_unit=float(centre_unit),
                       centre_tolerance=float(centre_tolerance), start_speed=int(start_speed))
