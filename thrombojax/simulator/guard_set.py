"""The guards a rollout applies after every learned step, as one pytree (:class:`GuardSet`).

A rollout with guards runs, inside its compiled ``lax.scan``::

    s_{t+1} = learned step (s_{t-1}, s_t)
    s_{t+1} = s_t + pace (s_{t+1} - s_t)   # off by default: the clot's step scaled, see below
    s_{t+1} = centring(s_{t+1})      # off by default: the clot's centroid held near the middle
    s_{t+1} = coherence(s_{t+1})     # the clot keeps its shape within `tolerance` of a rigid copy
    s_{t+1} = contain(s_{t+1})       # clot nodes that crossed the rigid wall are put back inside

and records per step how far each guard moved every node (``corrections``): a large correction
means the model is wrong, and the reports show it. The next step's velocity is taken from the
corrected positions (position-based dynamics), unless ``keep_velocity`` (coherence's move) or
``keep_velocity_wall`` (containment's) keep the step's own. Guards act on clot rows only
(gathered with the host-side index ``clot_index``), so the cost does not grow with the vessel.

Distances are in the rollout's (scaled) coordinates; :func:`build_guards` takes them in vessel
radii and converts with ``radius`` (one vessel radius in scaled coordinates). Defaults:
containment on with a 0.01 r margin and 0.01 r tolerance (about the solver's contact
penetration), coherence on with a 1 r tolerance (the true clot deviates from a rigid copy of its
start by at most 0.50 r on BendVessel and 0.61-1.30 r on ClotEntry,
``experiments/results/ladder_budget/coherence_auto/fit_table.md``, so at 1 r coherence acts
mainly on a clot that falls apart; ``thrombojax rollout --coherence-tolerance auto`` fits a
tighter one on the run's training simulations, :mod:`thrombojax.eval.coherence_fit`) and full
stiffness. Centring (:func:`~thrombojax.simulator.centring.centre_clot`) is off
unless a tolerance is given (``centring_r``).

Pace (off unless ``pace`` is given) is a calibration rather than a guard: every clot node's
learned step ``s_{t+1} - s_t`` is multiplied by ``pace`` before the guards act, so that a model
whose clot runs along the vessel too fast or too slow can be slowed down or sped up
(:mod:`thrombojax.eval.pace_fit` fits it on validation simulations; measured on ClotEntry, a
pace fitted on one vessel does not carry over to others). It acts on the step of one state (a
member's own, or a committee's mean), never on an ensemble's averaged output, so
:meth:`GuardSet.apply` does not include it: the rollouts call :meth:`GuardSet.advance` (pace,
then the guards, and the previous frame the next step reads).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from thrombojax.errors import ConfigError
from thrombojax.simulator.centring import centre_clot, centre_lengths
from thrombojax.simulator.guards import coherence, contain
from thrombojax.simulator.wall import Wall, nearest_wall_point
from thrombojax.simulator.wall_build import wall_from_simulation
from thrombojax.types import NodeType

__all__ = ["GuardSet", "build_guards", "GUARD_NAMES", "FIXED_COHERENCE_R"]

GUARD_NAMES: tuple[str, ...] = ("centring", "coherence", "containment")

FIXED_COHERENCE_R: float = 1.0
""":func:`build_guards`'s coherence tolerance in vessel radii when none is given (``thrombojax
rollout`` fits one on the run's training simulations instead, when it can)."""


@struct.dataclass
class GuardSet:
    """The guards of one rollout (a pytree: arrays and the guards' distances and factors
    traced, so a rollout at another tolerance, margin, stiffness or pace runs the same compiled
    program; the switches and the centring guard's search lengths static).

    Attributes:
        clot_index: ``[C]`` int32 indices of the clot rows the guards act on.
        wall: the rigid :class:`~thrombojax.simulator.wall.Wall` (scaled coordinates).
        x_ref: ``[C, 3]`` the clot's reference shape (its positions at the rollout's start).
        containment: apply :func:`~thrombojax.simulator.guards.contain`.
        margin, tol: containment distances (scaled coordinates).
        coherence: apply :func:`~thrombojax.simulator.guards.coherence`.
        stiffness, tolerance: coherence settings (tolerance in scaled coordinates).
        keep_centroid: coherence leaves the clot's centroid where the step put it
            (:func:`~thrombojax.simulator.guards.coherence`'s ``keep_centroid``).
        keep_velocity: the step after reads the clot's velocity from before coherence (the
            previous frame moves with coherence's correction, :meth:`advance`): coherence
            corrects where the clot is, not how fast its nodes move; containment's
            correction still changes the velocity, unless ``keep_velocity_wall``.
        keep_velocity_wall: the same for containment: the step after reads the velocity from
            before containment (a node put back inside keeps moving as the step moved it).
        free_past_end: coherence fits and moves only the clot nodes the vessel still holds:
            nodes past an open end of the wall (the clot leaving through the outlet,
            :class:`~thrombojax.simulator.wall.WallQuery`'s ``past_end``) are neither pulled
            nor part of the fit (static; one more wall query per step).
        max_stretch, stretching: coherence's copy of the rest shape may stretch, without a
            change of volume, by principal stretches within ``[1 / max_stretch, max_stretch]``
            (:func:`~thrombojax.simulator.guards.coherence`'s ``max_stretch``), when
            ``stretching``; else it is rigid.
        centring: apply :func:`~thrombojax.simulator.centring.centre_clot` first.
        centre_tolerance, centre_lengths: its tolerance and ``(axis_radius, slab, reach)``
            (scaled coordinates).
        pace: ``[]`` the factor on every clot node's learned step (traced: a new value does not
            compile again). pacing: apply it (:meth:`pace_step`).
    """

    clot_index: jax.Array
    wall: Wall
    x_ref: jax.Array
    containment: bool = struct.field(pytree_node=False, default=True)
    margin: jax.Array | float = 0.0
    tol: jax.Array | float = 0.0
    coherence: bool = struct.field(pytree_node=False, default=True)
    stiffness: jax.Array | float = 1.0
    tolerance: jax.Array | float = 0.0
    keep_centroid: bool = struct.field(pytree_node=False, default=False)
    keep_velocity: bool = struct.field(pytree_node=False, default=False)
    keep_velocity_wall: bool = struct.field(pytree_node=False, default=False)
    free_past_end: bool = struct.field(pytree_node=False, default=False)
    max_stretch: jax.Array | float = 1.0
    stretching: bool = struct.field(pytree_node=False, default=False)
    centring: bool = struct.field(pytree_node=False, default=False)
    centre_tolerance: jax.Array | float = 0.0
    centre_lengths: tuple[float, float, float] = struct.field(pytree_node=False,
                                                              default=(1.0, 1.0, 1.0))
    pace: jax.Array | float = 1.0
    pacing: bool = struct.field(pytree_node=False, default=False)

    def pace_step(self, cur: jax.Array, nxt: jax.Array) -> tuple[jax.Array, dict[str, jax.Array]]:
        """The learned step ``cur -> nxt`` (``[N, 3]`` each) of the clot rows times ``pace``;
        returns ``(nxt, {"pace": how far every node was moved [N]})``, or ``(nxt, {})`` exactly
        when pacing is off."""
        if not self.pacing:
            return nxt, {}
        idx = self.clot_index
        step = nxt[idx] - cur[idx]
        moved = (self.pace - 1.0) * step
        shift = jnp.sqrt(jnp.sum(moved * moved, axis=-1))
        return (nxt.at[idx].set(cur[idx] + self.pace * step),
                {"pace": jnp.zeros(nxt.shape[0], nxt.dtype).at[idx].set(shift)})

    def advance(self, shift, prev: jax.Array, cur: jax.Array, nxt: jax.Array
                ) -> tuple[jax.Array, jax.Array, dict[str, jax.Array]]:
        """What a rollout does after the learned step ``cur -> nxt`` (``[N, 3]`` each) of one
        state: :meth:`pace_step`, then :meth:`apply`. Returns ``(prev', nxt', corrections)``:
        the next state's history ``prev' = shift(prev, cur)`` (``shift``: the step's
        :meth:`~thrombojax.simulator.step.LearnedStep.shift`), or with ``keep_velocity`` and/or
        ``keep_velocity_wall`` ``shift(prev, cur + m)``, ``m`` every node's move by coherence
        and/or containment, so that ``nxt' - prev'`` keeps the velocity those guards took out;
        the corrected ``nxt'``; pace's and the guards' corrections together."""
        nxt, paced = self.pace_step(cur, nxt)
        nxt, guarded, moved = self._apply(nxt)
        return shift(prev, cur if moved is None else cur + moved), nxt, paced | guarded

    def apply(self, x: jax.Array) -> tuple[jax.Array, dict[str, jax.Array]]:
        """Correct one frame ``x [N, 3]``; returns ``(x, {guard name: correction [N]})``.

        Nodes outside ``clot_index`` are never moved (their correction is 0).
        """
        x, corrections, _ = self._apply(x)
        return x, corrections

    def _apply(self, x):
        """:meth:`apply`, and the move of every node ``[N, 3]`` the next step's velocity keeps:
        coherence's when ``keep_velocity``, plus containment's when ``keep_velocity_wall`` (None
        when neither)."""
        n = x.shape[0]
        kept = None
        idx = self.clot_index
        xc = x[idx]
        ones = jnp.ones(idx.shape[0], bool)
        corrections = {}
        if self.centring:
            axis_radius, slab, reach = self.centre_lengths
            xc, shifted = centre_clot(xc, self.wall, tolerance=self.centre_tolerance,
                                      axis_radius=axis_radius, slab=slab, reach=reach)
            corrections["centring"] = jnp.zeros(n, x.dtype).at[idx].set(shifted)
        if self.coherence:
            before = xc
            held = ~nearest_wall_point(xc, self.wall).past_end if self.free_past_end else ones
            xc, shifted = coherence(xc, self.x_ref, held, stiffness=self.stiffness,
                                    tolerance=self.tolerance, keep_centroid=self.keep_centroid,
                                    max_stretch=self.max_stretch if self.stretching else None)
            corrections["coherence"] = jnp.zeros(n, x.dtype).at[idx].set(shifted)
            if self.keep_velocity:
                kept = xc - before
        if self.containment:
            before = xc
            xc, shifted = contain(xc, ones, self.wall, margin=self.margin, tol=self.tol)
            corrections["containment"] = jnp.zeros(n, x.dtype).at[idx].set(shifted)
            if self.keep_velocity_wall:
                kept = xc - before if kept is None else kept + xc - before
        moved = None if kept is None else jnp.zeros_like(x).at[idx].set(kept)
        return x.at[idx].set(xc), corrections, moved


def build_guards(
    wall_positions: np.ndarray,
    wall_node_type: np.ndarray,
    x_start: np.ndarray,
    node_type: np.ndarray,
    *,
    radius: float,
    wall_cells: np.ndarray | None = None,
    containment: bool = True,
    coherence: bool = True,
    margin_r: float = 0.01,
    tol_r: float = 0.01,
    stiffness: float = 1.0,
    tolerance_r: float = FIXED_COHERENCE_R,
    keep_centroid: bool = False,
    keep_velocity: bool = False,
    keep_velocity_wall: bool = False,
    free_past_end: bool = False,
    max_stretch: float | None = None,
    centring_r: float | None = None,
    pace: float | None = None,
) -> GuardSet:
    """Build the guards of one rollout on the host.

    Args:
        wall_positions: ``[N_full, 3]`` a frame of the full simulation (scaled), whose vessel
            nodes (and ``wall_cells``) make the wall; the vessel is rigid, any frame does.
        wall_node_type: ``[N_full]`` NodeType of that frame.
        x_start: ``[N, 3]`` the rollout's start frame s_{t0} on the rolled-out node set (scaled):
            the clot's reference shape.
        node_type: ``[N]`` NodeType of the rolled-out nodes.
        radius: one vessel radius in scaled coordinates (> 0).
        wall_cells: ``[F, 3]`` wall triangles of the full simulation, if it has them (exact
            wall), else the wall is its nodes with estimated normals.
        containment, coherence: switch each guard.
        margin_r, tol_r: containment margin and tolerance, in vessel radii.
        stiffness: coherence stiffness in [0, 1]. tolerance_r: coherence tolerance in radii.
        keep_centroid: coherence leaves the clot's centroid where the step put it.
        keep_velocity: the step after reads the velocity from before coherence
            (:meth:`GuardSet.advance`).
        keep_velocity_wall: the step after reads the velocity from before containment.
        free_past_end: coherence leaves alone the clot nodes past an open end of the wall
            (the part of the clot that has left the vessel) and fits its copy to the others.
        max_stretch: coherence's copy of the rest shape may stretch, without a change of
            volume, up to this principal stretch (>= 1); None: a rigid copy.
        centring_r: the centring guard's tolerance in radii (>= 0; the clot's centroid may lie
            this far from the middle of the vessel's cross-section); None: no centring.
        pace: the factor on every clot node's learned step before the guards (> 0; 1 leaves the
            step as it is); None: off (:meth:`GuardSet.pace_step`).
    Returns:
        The :class:`GuardSet`.
    """
    if not radius > 0:
        raise ConfigError(f"guards: the vessel radius must be > 0 (scaled units), got {radius}")
    if not 0.0 <= stiffness <= 1.0:
        raise ConfigError(f"guards: coherence stiffness must be in [0, 1], got {stiffness}")
    if max_stretch is not None and not (np.isfinite(max_stretch) and max_stretch >= 1):
        raise ConfigError(f"guards: the coherence guard's max_stretch must be a number >= 1, "
                          f"got {max_stretch}")
    if centring_r is not None and not centring_r >= 0:
        raise ConfigError(f"guards: the centring tolerance must be >= 0 radii, got {centring_r}")
    if pace is not None and not (np.isfinite(pace) and pace > 0):
        raise ConfigError(f"guards: the pace must be a number > 0, got {pace}")
    clot = np.flatnonzero(np.asarray(node_type) == NodeType.CLOT).astype(np.int32)
    if clot.size == 0:
        raise ConfigError("guards: the rolled-out node set has no clot node")
    wall = wall_from_simulation(np.asarray(wall_positions, np.float32),
                                np.asarray(wall_node_type), wall_cells)
    return GuardSet(
        clot_index=jnp.asarray(clot),
        wall=wall,
        x_ref=jnp.asarray(np.asarray(x_start, np.float32)[clot]),
        containment=bool(containment), margin=float(margin_r * radius),
        tol=float(tol_r * radius), coherence=bool(coherence), stiffness=float(stiffness),
        tolerance=float(tolerance_r * radius), keep_centroid=bool(keep_centroid),
        keep_velocity=bool(keep_velocity), keep_velocity_wall=bool(keep_velocity_wall),
        free_past_end=bool(free_past_end),
        max_stretch=float(max_stretch or 1.0), stretching=max_stretch is not None,
        centring=centring_r is not None,
        centre_tolerance=float((centring_r or 0.0) * radius),
        centre_lengths=centre_lengths(radius),
        pace=jnp.asarray(1.0 if pace is None else pace, jnp.float32), pacing=pace is not None,
    )
