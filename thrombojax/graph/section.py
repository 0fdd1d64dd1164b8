"""The vessel's width where the clot stands, as a node input.

Why: a clot pushed through a tapering, wobbling vessel slows where the vessel narrows and
speeds up where it widens. Rolled out, the ClotEntry ensembles answer too weakly: on a
held-out vessel whose true clot slows to 70 % of its speed through a narrow stretch the
seven-member ensemble kept 1.1-1.5 times the true speed there, then ran at 0.8 times the
true speed where the vessel widened (``speed_per_step_r`` against ``speed_true_per_step_r`` in
``experiments/results/ladder_budget/clotentry_pace/heldout/e7_guards.json``).
The clearance (:mod:`thrombojax.graph.clearance`, the centroid's distance to the nearest wall
node) gives a step the width, and a step trained with it follows it closely, but it also reads
how far the clot has drifted across the vessel: a clot 0.5 r off the axis reads a vessel half
as wide, and the clearance-trained steps slowed their drifting clots to 7-13 r behind the
truth (``experiments/results/ladder_budget/clotentry_clearance/README.md``). This module
reads the width of the vessel's cross-section itself, which does not change when the clot
moves across it.

At a point ``p`` (``unit`` a vessel radius):

1. the local axis ``t``: the direction of largest spread of the vessel nodes weighted by
   ``exp(-|x_j - p|^2 / (2 unit)^2)`` (along a tube about four times its spread across);
2. the cross-section: vessel nodes weighted by a slab across ``t`` and a wide ball,
   ``w_j = exp(-((x_j - p) . t)^2 / unit^2) exp(-|x_j - p|^2 / (4 unit)^2)`` (the ball keeps
   other turns of a tortuous vessel out); ``m`` their weighted mean, a point on the axis;
3. the width ``R``: the weighted RMS distance of those nodes from the line through ``m``
   along ``t``. The wall nodes of a tube of radius ``r`` give ``R = r`` wherever ``p`` lies in
   the section.

The feature is ``R`` at the clot's centroid over ``unit``, on every real clot node. Along the
true tracks of the ten ClotEntry simulations it correlates with the clot's speed +0.46 to
+0.94, about as the clearance does there (+0.52 to +0.86;
``experiments/results/ladder_budget/clotentry_section/width_track.json``): what it adds is
that a clot off the true track reads the same width. Invariant to rotations and
translations; a constant to differentiation; jittable, ``O(N)`` (no pairwise search).

Measured as an input of one rung's ClotEntry ensembles it made their rollouts end further off
(1.24-1.47 r without it, 2.26-2.36 r with it: the same narrowing slows one simulation's clot
by 30 % and another's by 8 %); not a default
(``experiments/results/ladder_budget/clotentry_section/README.md``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.types import NodeType, clot_mask

__all__ = ["SECTION_FEATURES", "section_width", "clot_section_features", "section_offset",
           "centre_pull"]

SECTION_FEATURES: int = 1
"""Width of :func:`clot_section_features`."""

_AXIS_WIDTH = 2.0  # the axis's Gaussian window, in units
_SLAB = 1.0  # the cross-section's half-width along the axis, in units
_BALL = 4.0  # the cross-section's reach from p, in units


def _weighted_mean(w: jax.Array, x: jax.Array) -> tuple[jax.Array, jax.Array]:
    total = jnp.sum(w)
    return jnp.sum(w[:, None] * x, axis=0) / jnp.maximum(total, 1e-30), total


def _clot_centroid(what: str, x, node_type, mask, name: str, length: float):
    """``(x, clot, vessel, c, n_clot)``: ``x`` a constant to differentiation, the real clot and
    vessel nodes, the clot's centroid and node count; raises ValueError naming ``what`` when
    the length ``name`` is not > 0."""
    if not length > 0:
        raise ValueError(f"{what}: {name} must be > 0, got {length!r}")
    x = jax.lax.stop_gradient(x)
    mask = jnp.asarray(mask, bool)
    clot = clot_mask(node_type, mask)
    vessel = mask & (jnp.asarray(node_type) == NodeType.VESSEL)
    c, n_clot = _weighted_mean(clot.astype(x.dtype), x)
    return x, clot, vessel, c, n_clot


def _section(x: jax.Array, vessel: jax.Array, p: jax.Array, unit: float,
             t: jax.Array | None = None):
    """``(R, t, m, ok)`` of the module's steps 1-3 at ``p`` (``t`` given: the axis is not
    estimated; ``m`` the cross-section's weighted mean, a point on the axis)."""
    d = x - p
    sq = jnp.sum(d * d, axis=-1)
    wa = jnp.where(vessel, jnp.exp(-sq / (_AXIS_WIDTH * unit) ** 2), 0.0)
    centre, total_a = _weighted_mean(wa, x)
    if t is None:
        dc = x - centre
        cov = jnp.einsum("n,ni,nj->ij", wa, dc, dc) / jnp.maximum(total_a, 1e-30)
        t = jnp.linalg.eigh(cov)[1][:, -1]  # the largest spread: along the vessel
    along = d @ t
    w = jnp.where(vessel, jnp.exp(-along ** 2 / (_SLAB * unit) ** 2
                                  - sq / (_BALL * unit) ** 2), 0.0)
    m, total = _weighted_mean(w, x)
    dm = x - m
    perp = dm - (dm @ t)[:, None] * t
    r2 = jnp.sum(w * jnp.sum(perp * perp, axis=-1)) / jnp.maximum(total, 1e-30)
    ok = (total_a > 1e-12) & (total > 1e-12)
    return jnp.where(ok, jnp.sqrt(jnp.where(ok, r2, 0.0)), 0.0), t, m, ok


def section_width(x: jax.Array, vessel: jax.Array, p: jax.Array, *, unit: float
                  ) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The vessel's width and axis at the point ``p`` (the module's steps 1-3). Jittable.

    Args:
        x: ``[N, 3]`` positions. vessel: ``[N]`` bool, the real vessel nodes. p: ``[3]``.
        unit: a vessel radius (> 0, units of ``x``): the windows' widths are multiples of it.
    Returns:
        ``(R [], t [3], ok [])``: the width (units of ``x``), the unit axis (sign arbitrary) and
        whether any vessel node lies within reach of ``p`` (``R`` is 0 where not).
    """
    width, t, _, ok = _section(x, vessel, p, unit)
    return width, t, ok


def clot_section_features(
    x: jax.Array, node_type: jax.Array, mask: jax.Array, *, scale: float,
) -> jax.Array:
    """``[N, 1]``: the vessel's width at the centroid of the real clot nodes of ``x``, over
    ``scale``, on every real clot node (see the module docstring); zeros on every other node,
    and everywhere when the frame has no real clot node or no vessel node within reach.

    Args:
        x: ``[N, 3]`` positions. node_type: ``[N]`` NodeType. mask: ``[N]`` real nodes.
        scale: a vessel radius (> 0, units of ``x``): the windows' unit and the divisor.
    Raises:
        ValueError: ``scale`` not > 0.
    """
    x, clot, vessel, c, n_clot = _clot_centroid("section features", x, node_type, mask,
                                                 "scale", scale)
    width, _, ok = section_width(x, vessel, c, unit=scale)
    keep = clot & (n_clot > 0) & ok
    return jnp.where(keep, width / scale, 0.0)[:, None].astype(x.dtype)


def section_offset(
    x: jax.Array, node_type: jax.Array, mask: jax.Array, *, unit: float,
    axis: jax.Array | None = None,
) -> tuple[jax.Array, jax.Array]:
    """How far the clot's centroid lies off the middle of the vessel's cross-section.

    The middle is the weighted mean ``m`` of the cross-section's vessel nodes of
    :func:`section_width` at the centroid ``c`` of the real clot nodes (a ring of wall round
    the axis averages to the axis point); the offset is ``c - m`` without its part along the
    axis ``t``. Near an open end the cross-section is not a ring (its nodes lie on one side of
    ``c`` along the axis): where ``|(m - c) . t|`` exceeds half the slab (``unit / 2``) there is
    no middle (``ok`` False, offset 0), as the centring guard stands aside there
    (:mod:`thrombojax.simulator.centring`). The section's ball weighs the nearer wall a
    little more: a clot 0.4 r off the axis of a straight tube reads 0.38 r. Vessel nodes only
    (no wall triangles or normals), so it runs inside a learned step on any solver's vessel.
    A constant to differentiation; jittable, ``O(N)``.

    Args:
        x: ``[N, 3]`` positions. node_type: ``[N]`` NodeType. mask: ``[N]`` real nodes.
        unit: a vessel radius (> 0, units of ``x``).
        axis: ``[N, 3]`` the vessel's local axis at every node
            (:func:`thrombojax.graph.vessel_axis.vessel_axis`, from the wall's normals): the
            section is then cut across their clot-wide mean, which holds at an open end, where
            the spread of :func:`section_width` turns into the end's ring. None: that spread.
    Returns:
        ``(offset [3], ok [])`` in the units of ``x``.
    """
    x, clot, vessel, c, n_clot = _clot_centroid("section offset", x, node_type, mask, "unit",
                                                 unit)
    t = None
    if axis is not None:  # the clot's mean axis, sign-free: the main direction of t_i t_i^T
        a = jnp.where(clot[:, None], jax.lax.stop_gradient(axis), 0.0)
        t = jnp.linalg.eigh(jnp.einsum("ni,nj->ij", a, a))[1][:, -1]
    _, t, m, ok = _section(x, vessel, c, unit, t)
    if axis is not None:
        ok = ok & (jnp.sum(a * a) > 0)
    e = c - m
    balance = jnp.dot(e, t)
    ok = ok & (n_clot > 0) & (jnp.abs(balance) <= 0.5 * _SLAB * unit)
    return jnp.where(ok, e - balance * t, 0.0), ok


def centre_pull(
    x: jax.Array, node_type: jax.Array, mask: jax.Array, *, unit: float, strength: float,
    tolerance: float = 0.0, axis: jax.Array | None = None,
) -> jax.Array:
    """``[3]``: the displacement that takes ``strength`` of the clot centroid's offset from the
    cross-section's middle (:func:`section_offset`) beyond ``tolerance`` back, ``-strength (e -
    clip(e, tolerance))``; zero within the tolerance and where there is no middle.

    The centring pull of a learned step's vessel-following prior
    (``LearnedStep.centre_pull``): the prior alone turns every clot node onto the vessel's axis
    but has nothing that brings a clot back to the middle, and on BendVessel it carries the
    clot 0.35 r off the middle within 8 steps, with a quarter of the clot outside the wall
    (``experiments/results/ladder_budget/bendvessel_hold/prior_drift.md``).

    Args:
        x: ``[N, 3]`` positions. node_type: ``[N]`` NodeType. mask: ``[N]`` real nodes.
        unit: a vessel radius (> 0, units of ``x``). strength: the share of the excess
            offset taken back per call, in [0, 1]. tolerance: offset left alone (>= 0, units
            of ``x``). axis: see :func:`section_offset`.
    """
    e, _ = section_offset(x, node_type, mask, unit=unit, axis=axis)
    size = jnp.sqrt(jnp.sum(e * e))
    excess = e * jnp.maximum(1.0 - tolerance / jnp.maximum(size, 1e-30), 0.0)
    return -strength * excess
