"""The clot's shape along its motion, as node inputs: where each node sits in the clot and how
long and wide the whole clot is.

Why: rolled out alone, the vessel-frame BendVessel models' clots stretch along their motion
(the front runs up to 6 r ahead of the true front while the rear keeps to the true rear), and a
step keeps 92-97 % of a stretch it is given even when trained with stretch noise 0.1
(``experiments/results/ladder_budget/bendvessel_shapes/stretch/README.md``). A stretch is a
property of the whole clot: a message-passing step with a few blocks sees only its graph
neighbours' displacements, where a 10 % stretch is a small change of edge lengths, so it cannot
tell a stretched clot from a true one. These features give every clot node the clot-wide
figures.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.types import clot_mask

__all__ = ["CLOT_SHAPE_FEATURES", "clot_motion", "clot_shape_features"]

CLOT_SHAPE_FEATURES: int = 3
"""Width of :func:`clot_shape_features`."""


def clot_motion(x_prev: jax.Array, x_cur: jax.Array,
                clot: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``(centre [3], u [3])``: the centroid of the ``clot`` nodes (``[N]`` bool) of s_t and
    the clot's direction of motion, its mean displacement from s_{t-1}, unit (zero at rest or
    with no clot node). Jittable; safe to differentiate at rest."""
    w = clot.astype(x_cur.dtype)[:, None]
    count = jnp.maximum(jnp.sum(w), 1.0)
    v = jnp.sum((x_cur - x_prev) * w, axis=0) / count
    speed = jnp.sqrt(jnp.sum(v * v))
    u = jnp.where(speed > 0, v / jnp.where(speed > 0, speed, 1.0), 0.0)
    return jnp.sum(x_cur * w, axis=0) / count, u


def clot_shape_features(
    x_prev: jax.Array, x_cur: jax.Array, node_type: jax.Array, mask: jax.Array, *,
    scale: float,
) -> jax.Array:
    """``[N, 3]``: each clot node's place along the clot's motion, and the clot's length and width.

    With ``c`` the centroid of the real clot nodes of s_t and ``u`` the clot's direction of motion
    (its mean displacement from s_{t-1}, unit; zero at rest), per real clot node ``i``:
    ``[(x_i - c) . u / L, sigma_along / L, sigma_across / L]``, ``sigma_along`` the RMS over the
    clot of ``(x_j - c) . u`` and ``sigma_across`` the RMS per axis of the offsets' parts across
    ``u`` (at rest: of the whole offsets). A stretch along the motion by ``1 + e`` multiplies
    the first two by ``1 + e`` and leaves the third. Invariant to rotations and translations; a
    constant to differentiation. Jittable, ``O(N)``.

    Args:
        x_prev, x_cur: ``[N, 3]`` positions s_{t-1}, s_t. node_type: ``[N]`` NodeType.
        mask: ``[N]`` real nodes. scale: ``L`` (> 0, units of ``x``; a vessel radius).
    Returns:
        The three columns on real clot nodes, zeros on every other node.
    Raises:
        ValueError: ``scale`` not > 0.
    """
    if not scale > 0:
        raise ValueError(f"clot shape features: scale must be > 0, got {scale!r}")
    x_prev, x_cur = jax.lax.stop_gradient(x_prev), jax.lax.stop_gradient(x_cur)
    clot = clot_mask(node_type, jnp.asarray(mask, bool))
    w = clot.astype(x_cur.dtype)[:, None]
    count = jnp.maximum(jnp.sum(w), 1.0)
    centre, u = clot_motion(x_prev, x_cur, clot)
    rel = (x_cur - centre) * w
    along = rel @ u
    across = rel - along[:, None] * u
    moving = jnp.sum(u * u)  # 1 moving (across u: 2 axes), 0 at rest (all 3)
    sigma_along = jnp.sqrt(jnp.sum(along ** 2) / count)
    sigma_across = jnp.sqrt(jnp.sum(across ** 2) / (count * (3.0 - moving)))
    feats = jnp.stack([along, jnp.full_like(along, sigma_along),
                       jnp.full_like(along, sigma_across)], axis=-1) / scale
    return jnp.where(clot[:, None], feats, 0.0)
