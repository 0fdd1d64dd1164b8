"""The vessel's local axis at every clot node, and the velocity split along and across it.

A clot in a vessel is driven along the vessel (a flow, an aspiration, a catheter) and held off
the wall; a rollout that drifts fails by moving across the vessel (into the wall) or by losing
its speed along it. The velocity alone does not say which part of it is which: the model must
work the vessel's direction out of the wall nodes in its graph. These features give it the
split directly, from the geometry alone (no solver quantity, so they mean the same on any
solver's vessels):

* the local axis ``t_i`` of the vessel at clot node ``i``: the direction orthogonal to the wall
  normals around it, i.e. the eigenvector with the smallest eigenvalue of
  ``M_i = sum_j w_ij n_j n_j^T`` over vessel nodes ``j`` (Gaussian weights
  ``w_ij = exp(-|x_j - x_i|^2 / rho^2)``; ``n_j`` the wall normal of
  :func:`thrombojax.graph.wall_nodes.local_wall_plane`). The normals of a tube are all
  orthogonal to its axis, so ``t_i`` is the tube's axis; in a bend it follows the bend.
* the velocity ``v_i = s_t - s_{t-1}`` split into ``(v_i . t_i) t_i`` (along the vessel) and the
  rest (across it). Both are independent of the sign of ``t_i``, which the geometry cannot fix,
  and rotate with the input (a global rotation of the frame rotates both parts).

Jittable, dense (``N x N``): meant for training-size clouds, as the signed wall features
(:data:`thrombojax.graph.wall_nodes.DENSE_PLANE_NODES` nodes at most).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.graph.clot_shape import clot_motion
from thrombojax.graph.wall_nodes import (
    clot_wall_mean,
    local_wall_plane,
    pairwise_sq_distances,
    vessel_normals,
)
from thrombojax.types import NodeType, clot_mask

__all__ = ["vessel_axis", "axis_velocity_features", "axis_speed_velocity", "follow_axis_offset",
           "clot_lateral_mean", "outlet_features"]


def vessel_axis(
    x: jax.Array, node_type: jax.Array, mask: jax.Array, *, radius: float,
    patch: jax.Array | None = None,
) -> jax.Array:
    """Unit local vessel axis at every node (sign arbitrary). Jittable.

    Args:
        x: ``[N, 3]`` positions (gradients are stopped). node_type: ``[N]`` NodeType.
        mask: ``[N]`` real nodes.
        radius: ``rho``, the width of the Gaussian weights over vessel nodes (> 0, units of
            ``x``); about two vessel radii takes in the wall all round a clot node.
        patch: the vessel's wall search made before
            (:func:`~thrombojax.graph.wall_nodes.wall_patches` of a frame with the same vessel
            nodes, e.g. a rollout's first): the same axis without the ``N x N`` search
            (:func:`~thrombojax.graph.wall_nodes.vessel_normals`). None: search ``x``.
    Returns:
        ``[N, 3]`` unit vectors; zeros on every node when there is no real vessel node or no
        real clot node (:func:`~thrombojax.graph.wall_nodes.local_wall_plane` gives no normals).
    """
    if not radius > 0:
        raise ValueError(f"vessel axis: radius must be > 0, got {radius!r}")
    x = jax.lax.stop_gradient(x)
    mask = jnp.asarray(mask, bool)
    vessel = mask & (jnp.asarray(node_type) == NodeType.VESSEL)
    if patch is None:
        _, normal = local_wall_plane(x, node_type, mask)
    else:  # only the vessel rows of the normals are read below
        normal = vessel_normals(x, node_type, mask, patch)
    w = jnp.where(vessel[None, :], jnp.exp(-pairwise_sq_distances(x) / radius**2), 0.0)  # [N, N]
    m = jnp.einsum("nj,ja,jb->nab", w, normal, normal)
    _, vecs = jnp.linalg.eigh(m)
    axis = vecs[:, :, 0]  # the direction of least normal: along the vessel
    ok = jnp.any(jnp.linalg.norm(normal, axis=-1) > 0)
    return jnp.where(ok, axis, 0.0)


def axis_velocity_features(
    x_prev: jax.Array, x_cur: jax.Array, node_type: jax.Array, mask: jax.Array, *,
    radius: float, velocity_scale: jax.Array | float = 1.0, patch: jax.Array | None = None,
    axis: jax.Array | None = None,
) -> jax.Array:
    """``[N, 6]``: the velocity along the local vessel axis and across it, on clot nodes.

    Args:
        x_prev, x_cur: ``[N, 3]`` positions s_{t-1}, s_t. node_type: ``[N]`` NodeType.
        mask: ``[N]`` real nodes. radius: see :func:`vessel_axis`.
        velocity_scale: both parts are divided by it (the step's velocity normalisation).
        patch: a wall search made before (:func:`vessel_axis`); None: search ``x_cur``.
        axis: :func:`vessel_axis` of ``x_cur`` computed before (then ``radius`` and ``patch``
            are not read); None: computed here.
    Returns:
        ``[(v . t) t, v - (v . t) t] / velocity_scale`` on real clot nodes, zeros elsewhere
        (``v = x_cur - x_prev``, ``t`` = :func:`vessel_axis` of ``x_cur``).
    """
    t = vessel_axis(x_cur, node_type, mask, radius=radius, patch=patch) if axis is None else axis
    v = (x_cur - x_prev) / velocity_scale
    along = jnp.sum(v * t, axis=-1, keepdims=True) * t
    feats = jnp.concatenate([along, v - along], axis=-1)
    return jnp.where(clot_mask(node_type, mask)[:, None], feats, 0.0)


def axis_speed_velocity(v: jax.Array, t: jax.Array) -> jax.Array:
    """``[N, 3]``: each velocity ``v_i`` turned onto its axis ``t_i`` at its speed,
    ``|v_i| sign(v_i . t_i) t_i`` (forward along the axis, whichever sign ``t_i`` has; the
    speed's gradient is defined at rest)."""
    along = jnp.sum(v * t, axis=-1, keepdims=True)
    speed = jnp.sqrt(jnp.maximum(jnp.sum(v * v, axis=-1, keepdims=True), 1e-30))
    return jnp.where(along < 0, -speed, speed) * t


def follow_axis_offset(
    x_prev: jax.Array, x_cur: jax.Array, node_type: jax.Array, mask: jax.Array, *,
    radius: float, patch: jax.Array | None = None, axis: jax.Array | None = None,
    pull: jax.Array | None = None,
) -> jax.Array:
    """``[N, 3]``: what turns each clot node's velocity onto the vessel's axis, keeping its speed.

    The vessel-following prior of a learned step: ``u_i = |v_i| sign(v_i . t_i) t_i - v_i``, so
    that ``s_t + v_i + u_i`` moves node ``i`` along the vessel at its current speed (no model:
    0.14x constant velocity over ClotEntry's rollouts, ``experiments/follow_axis.py``). Zero on
    nodes other than real clot nodes and where the axis is undefined (no vessel or clot).
    Differentiable in the velocity (the axis is a constant to it; the speed's gradient is
    defined at rest).

    Args:
        x_prev, x_cur: ``[N, 3]`` positions s_{t-1}, s_t. node_type: ``[N]`` NodeType.
        mask: ``[N]`` real nodes. radius, patch: see :func:`vessel_axis`.
        axis: see :func:`axis_velocity_features`.
        pull: ``[3]`` a displacement every clot node's turned velocity ``w_i`` is tilted by,
            at the same speed: ``|w_i| (w_i + pull) / |w_i + pull|`` (the centring pull of
            :func:`thrombojax.graph.section.centre_pull`; the speed is kept, so a pull repeated
            every step does not feed back into the clot's pace). None: no tilt.
    """
    t = vessel_axis(x_cur, node_type, mask, radius=radius, patch=patch) if axis is None else axis
    v = x_cur - x_prev
    w = axis_speed_velocity(v, t)
    if pull is not None:
        tilted = w + pull
        w = tilted * jnp.sqrt(jnp.maximum(jnp.sum(w * w, axis=-1, keepdims=True), 1e-30)
                              / jnp.maximum(jnp.sum(tilted * tilted, axis=-1, keepdims=True),
                                            1e-30))
    offset = w - v
    defined = jnp.sum(t * t, axis=-1, keepdims=True) > 0.5
    return jnp.where(clot_mask(node_type, mask)[:, None] & defined, offset, 0.0)


def clot_lateral_mean(
    accel: jax.Array, x: jax.Array, node_type: jax.Array, mask: jax.Array, *, radius: float,
    patch: jax.Array | None = None, axis: jax.Array | None = None,
) -> jax.Array:
    """``[N, 3]``: the clot-wide mean of the accelerations' parts across the vessel's axis.

    ``accel - clot_lateral_mean(accel, ...)`` keeps every clot node's acceleration along its
    local axis ``t_i`` and every difference between nodes (the clot's deformation), and takes
    out what would push the whole clot sideways, ``mean_j (a_j - (a_j . t_j) t_j)`` over the
    real clot nodes. A learned step with a lateral hold (``LearnedStep.lateral_radius``) moves
    its clot across the vessel only as the vessel turns (its prior) and as the clot deforms:
    learned rollouts fail by drifting sideways into the wall long before they lose their
    place along the vessel (``docs/rollouts.md``).

    Args:
        accel: ``[N, 3]`` accelerations (global frame). x: ``[N, 3]`` positions, the axis's.
        node_type: ``[N]`` NodeType. mask: ``[N]`` real nodes. radius, patch: see
            :func:`vessel_axis`. axis: see :func:`axis_velocity_features` (of ``x``).
    Returns:
        The mean on every real clot node, zeros elsewhere and everywhere when the axis is
        undefined (no real vessel or clot node). Linear in ``accel`` (the axis is constant).
    """
    t = vessel_axis(x, node_type, mask, radius=radius, patch=patch) if axis is None else axis
    clot = clot_mask(node_type, mask)[:, None]
    lateral = accel - jnp.sum(accel * t, axis=-1, keepdims=True) * t
    count = jnp.maximum(clot.sum(), 1)
    mean = jnp.where(clot, lateral, 0.0).sum(axis=0) / count
    defined = jnp.sum(t * t, axis=-1, keepdims=True) > 0.5
    return jnp.where(clot & defined, mean[None, :], 0.0)


def outlet_features(
    x_prev: jax.Array, x_cur: jax.Array, node_type: jax.Array, mask: jax.Array, *,
    radius: float,
) -> jax.Array:
    """``[N, 2]``: where the clot is against the vessel's open ends, ahead of its motion.

    A clot speeds up as it reaches the outlet (its flare, then the open end; BendVessel's true
    clot doubles its speed over the last 4-7 frames), and a step that reads only its graph
    neighbours and the velocity meets the outlet when its front is already in it.
    Per clot node ``i``: the Gaussian-weighted mean offset of the vessel nodes around it,
    ``m_i = sum_j w_ij (x_j - x_i) / sum_j w_ij`` (``w_ij = exp(-|x_j - x_i|^2 / rho^2)`` over
    real vessel nodes, as :func:`vessel_axis`), along the clot's direction of motion ``u``
    (its mean velocity, unit), over ``rho``: ``e_i = (m_i . u) / rho``. Inside a tube the
    vessel lies evenly before and behind a node (``e_i`` about 0); within about ``2 rho`` of an
    open end or a widening it does not: ``e_i < 0`` as the clot nears an outlet (the vessel is
    behind it), ``> 0`` as it leaves an inlet. Second column: the clot-wide mean of ``e``,
    which tells every node what the clot's front meets. Invariant to rotations and
    translations; a constant to differentiation.

    Args:
        x_prev, x_cur: ``[N, 3]`` positions s_{t-1}, s_t. node_type: ``[N]`` NodeType.
        mask: ``[N]`` real nodes. radius: ``rho`` (> 0, units of ``x``).
    Returns:
        ``[e_i, mean_j e_j]`` on real clot nodes, zeros elsewhere and everywhere when the clot is
        at rest or there is no real vessel node.
    """
    if not radius > 0:
        raise ValueError(f"outlet features: radius must be > 0, got {radius!r}")
    x_prev, x_cur = jax.lax.stop_gradient(x_prev), jax.lax.stop_gradient(x_cur)
    mask = jnp.asarray(mask, bool)
    clot = clot_mask(node_type, mask)
    vessel = mask & (jnp.asarray(node_type) == NodeType.VESSEL)
    w = jnp.where(vessel[None, :], jnp.exp(-pairwise_sq_distances(x_cur) / radius**2), 0.0)
    total = jnp.sum(w, axis=1)
    m = (w @ x_cur) / jnp.maximum(total, 1e-30)[:, None] - x_cur  # [N, 3]
    _, u = clot_motion(x_prev, x_cur, clot)
    e = jnp.where(clot & (total > 0), (m @ u) / radius, 0.0)[:, None]
    return jnp.concatenate([e, clot_wall_mean(e, node_type, mask)], axis=-1)
