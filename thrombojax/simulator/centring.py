"""The centring guard: the clot's centroid held near the middle of the vessel's cross-section.

Why: a learned ClotEntry rollout drifts sideways, 0.4-1.0 r off the true clot's track, while
the true clot's centroid stays near the middle of the vessel; a step that reads the geometry
around the clot (its clearance, its room) then reads a narrower vessel than the truth's and
slows its clot (``experiments/results/ladder_budget/clotentry_clearance/README.md``). Neither
containment (it moves only nodes that crossed the wall) nor coherence (it keeps the shape, not
the place) undoes a drift of the whole clot inside the vessel.

:func:`section_centre` finds the middle of the vessel's cross-section through a point ``c``
from the rigid wall alone (no centreline, so any solver's vessel does):

* the local axis ``t``: the eigenvector with the smallest eigenvalue of
  ``M = sum_f a_f w_f n_f n_f^T`` over wall elements ``f`` (triangles, weighted by their area
  ``a_f``; wall nodes weigh 1) with inward normals ``n_f`` and Gaussian weights
  ``w_f = exp(-|p_f - c|^2 / rho^2)``: a tube's normals are all orthogonal to its axis;
* the centre: ``c`` plus the weighted mean of the elements' offsets across ``t``,
  ``P (p_f - c)`` with ``P = I - t t^T``, weights ``a_f exp(-((p_f - c) . t)^2 / h^2)``, over
  elements within ``reach`` of ``c`` (the ring of wall around ``c``, not far parts of the vessel
  that cross the same plane). A ring of wall round the axis averages to the axis point.
* near an open end the cross-section is not a ring (the wall lies on one side of ``c`` along
  the axis): where the weighted mean of ``(p_f - c) . t`` exceeds ``h / 2`` in size, there is
  no centre (``ok`` False) and the guard stands aside, as containment does past an open end.
  The true ClotEntry clots lie within 0.3 r of the centre until their centroid reaches the
  outlet, and 0.6-2.4 r off it in the last frames, as they leave the vessel
  (``experiments/results/ladder_budget/clotentry_centring/README.md``).

:func:`centre_clot` moves the whole clot rigidly (every node by the same vector) so that its
centroid lies at most ``tolerance`` from that centre across the axis; a clot within the
tolerance is left exactly where it is. The shape is untouched, and the move is recorded as
every clot node's correction, as the other guards' are.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.simulator.wall import Wall, safe_norm

__all__ = ["CENTRE_AXIS_R", "CENTRE_SLAB_R", "CENTRE_REACH_R", "centre_lengths", "section_centre",
           "centre_clot"]

CENTRE_AXIS_R: float = 2.0
"""Width ``rho`` of the axis's Gaussian weights, in vessel radii (the wall all round ``c``)."""
CENTRE_SLAB_R: float = 0.5
"""Half-width ``h`` of the cross-section's Gaussian slab along the axis, in vessel radii."""
CENTRE_REACH_R: float = 3.0
"""Wall elements farther than this from ``c`` (vessel radii) do not count."""


def centre_lengths(radius: float) -> tuple[float, float, float]:
    """``(axis_radius, slab, reach)`` of :func:`section_centre` for a vessel of ``radius``
    (the module's ``CENTRE_*_R`` constants times it, in the wall's units)."""
    return tuple(float(k * radius) for k in (CENTRE_AXIS_R, CENTRE_SLAB_R, CENTRE_REACH_R))


def _elements(wall: Wall) -> tuple[jax.Array, jax.Array, jax.Array]:
    """``(points [F, 3], inward normals [F, 3], weights [F])`` of the wall's real elements."""
    v = wall.vertices
    points = v.mean(axis=1)
    if wall.kind == "triangles":
        area = 0.5 * safe_norm(jnp.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]))
    else:
        area = jnp.ones(v.shape[0], v.dtype)
    return points, wall.face_normal, jnp.where(wall.mask, area, 0.0)


def section_centre(
    c: jax.Array, wall: Wall, *, axis_radius: float, slab: float, reach: float
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The middle of the vessel's cross-section through ``c [3]``. Jittable.

    Args:
        c: ``[3]`` a point inside the vessel (the wall's coordinates).
        wall: the rigid :class:`~thrombojax.simulator.wall.Wall`.
        axis_radius, slab, reach: ``rho``, ``h`` and the reach of the module's formulas (> 0,
            the wall's units).
    Returns:
        ``(centre [3], axis [3], ok [])``: ``ok`` is False where no wall element lies within
        ``reach`` of ``c`` or ``c`` is at an open end (then ``centre`` is ``c``).
    """
    points, normals, area = _elements(wall)
    d = points - c
    dist2 = jnp.sum(d * d, axis=-1)
    near = jnp.where(dist2 < reach**2, area, 0.0)
    w = near * jnp.exp(-dist2 / axis_radius**2)
    m = jnp.einsum("f,fi,fj->ij", w, normals, normals)
    axis = jnp.linalg.eigh(m)[1][:, 0]
    along = d @ axis
    u = near * jnp.exp(-((along / slab) ** 2))
    total = jnp.sum(u)
    balance = jnp.sum(u * along) / jnp.where(total > 0, total, 1.0)  # ~0 inside a tube
    ok = (total > 0) & (jnp.sum(w) > 0) & (jnp.abs(balance) <= 0.5 * slab)
    lateral = d - along[:, None] * axis
    shift = jnp.sum(u[:, None] * lateral, axis=0) / jnp.where(ok, total, 1.0)
    return c + jnp.where(ok, shift, 0.0), axis, ok


def centre_clot(
    x: jax.Array, wall: Wall, *, tolerance: float, axis_radius: float, slab: float,
    reach: float,
) -> tuple[jax.Array, jax.Array]:
    """Move the clot ``x [C, 3]`` (its real nodes only) rigidly toward the cross-section's middle.

    With ``e`` the offset of the clot's centroid from :func:`section_centre` (across the axis),
    every node moves by ``-(e - clip(e, tolerance))``: nothing while
    ``|e| <= tolerance``. Jittable, vmappable.

    Args:
        x: ``[C, 3]`` the clot's nodes (all real).
        wall: the rigid wall. tolerance: offset allowed without correction (>= 0).
        axis_radius, slab, reach: see :func:`section_centre`.
    Returns:
        ``(x_new [C, 3], correction [C])``: positions and how far each node moved.
    """
    c = jnp.mean(x, axis=0)
    centre, _, ok = section_centre(c, wall, axis_radius=axis_radius, slab=slab, reach=reach)
    off = c - centre
    norm = safe_norm(off)
    excess = off * jnp.maximum(1.0 - tolerance / jnp.maximum(norm, 1e-30), 0.0)
    move = jnp.where(ok, -excess, 0.0)
    return x + move, jnp.broadcast_to(safe_norm(move), x.shape[:1])
