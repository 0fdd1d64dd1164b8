"""The clot's clearance, as a node input: how far the clot's centroid is from the nearest wall.

Why: in ClotEntry each clot's speed follows the vessel's width where it stands (within a
simulation, speed and the centroid's clearance correlate +0.45 to +0.77; a speed set from the
clearance alone, on the true track, ends 0.05 r from the true clot on ``clotentry_009``:
``experiments/results/clot_speed/README.md``). The clot's *room*
(:func:`thrombojax.graph.wall_nodes.clot_wall_mean`, the clot-wide mean of each node's clipped
distance to the wall) measures something close, but through the clot's own nodes: where the
containment guard puts a node that crossed the wall back inside, the room changes with the
guard's margin, and so does the rolled-out clot's speed (a margin of 0.2 r instead of 0.01 r
moves every guarded clot 1.1-2.5 r forward in 160 steps:
``experiments/results/ladder_budget/clotentry_speed_room/margin/README.md``). The clearance
reads the clot only through its centroid, which such corrections hardly move, and the rigid
wall, which they do not move at all.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.types import NodeType, clot_mask

__all__ = ["CLEARANCE_FEATURES", "clot_clearance"]

CLEARANCE_FEATURES: int = 1
"""Width of :func:`clot_clearance`."""


def clot_clearance(x: jax.Array, node_type: jax.Array, mask: jax.Array, *,
                   scale: float) -> jax.Array:
    """``[N, 1]``: the distance from the centroid of the real clot nodes of ``x`` to the nearest
    real vessel node, divided by ``scale``, on every real clot node; zeros on every other node,
    and everywhere when the frame has no real vessel node or no real clot node.

    Invariant to rotations and translations; a constant to differentiation (an input, like the
    graph). Jittable, ``O(N)``.

    Args:
        x: ``[N, 3]`` positions. node_type: ``[N]`` NodeType. mask: ``[N]`` real nodes.
        scale: the length the distance is divided by (> 0, units of ``x``; a vessel radius).
    Raises:
        ValueError: ``scale`` not > 0.
    """
    if not scale > 0:
        raise ValueError(f"clot clearance: scale must be > 0, got {scale!r}")
    x = jax.lax.stop_gradient(x)
    mask = jnp.asarray(mask, bool)
    clot = clot_mask(node_type, mask)
    vessel = mask & (jnp.asarray(node_type) == NodeType.VESSEL)
    w = clot.astype(x.dtype)[:, None]
    centre = jnp.sum(x * w, axis=0) / jnp.maximum(jnp.sum(w), 1.0)
    sq = jnp.where(vessel, jnp.sum((x - centre) ** 2, axis=-1), jnp.inf)
    nearest = jnp.min(sq)
    ok = jnp.any(vessel) & jnp.any(clot)
    clearance = jnp.where(ok, jnp.sqrt(jnp.where(ok, nearest, 0.0)), 0.0) / scale
    return jnp.where(clot & ok, clearance, 0.0)[:, None].astype(x.dtype)
