"""Per-node distance and direction to the nearest vessel node, under ``jit``, static shapes.

The wall features of a learned step (:class:`thrombojax.simulator.step.LearnedStep` with
``wall_cutoff > 0``): every clot node learns where the rigid wall is, also when no vessel node is
among its graph neighbours (a radius graph capped at K neighbours links a clot node inside the
clot only to clot nodes). The wall is represented by its nodes, which every dataset has (wall
triangles are optional), so the features need nothing but the frame itself::

    feats = wall_node_features(x, node_type, mask, cutoff=c)   # [N, 4]
    # [min(d, c) / c, unit vector to the nearest vessel node * (d < c)] on clot nodes, 0 elsewhere

The search is exact and dense: rows of ``block`` query nodes against all nodes, so the memory is
``block x N`` floats whatever ``N`` is (about 110 MB at 27,000 nodes). Distances are invariant
and directions rotate with the vessel, like the relative displacements a graph network sees.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.types import NodeType, clot_mask

__all__ = ["WALL_NODE_FEATURES", "clipped_distance_direction", "nearest_vessel_node",
           "wall_node_features"]

WALL_NODE_FEATURES: int = 4
"""Width of :func:`wall_node_features`: clipped distance / cutoff and a 3-D direction."""


def clipped_distance_direction(diff: jax.Array, cutoff: float) -> jax.Array:
    """``[..., 4]`` features of vectors ``diff [..., 3]`` from a node to its nearest wall point:
    ``min(d, cutoff) / cutoff`` and the unit vector times ``d < cutoff`` (zero when ``d`` is 0).
    The one formula of the wall features (also :func:`thrombojax.simulator.walls.wall_features`).
    """
    sq = jnp.sum(diff * diff, axis=-1)
    d = jnp.where(sq > 0, jnp.sqrt(jnp.where(sq > 0, sq, 1.0)), 0.0)  # zero gradient at 0
    near = (d < cutoff) & (d > 0)
    direction = jnp.where(near[..., None], diff / jnp.where(near, d, 1.0)[..., None], 0.0)
    return jnp.concatenate([jnp.minimum(d, cutoff)[..., None] / cutoff, direction], axis=-1)


def nearest_vessel_node(
    x: jax.Array, node_type: jax.Array, mask: jax.Array, *, block: int = 1024
) -> jax.Array:
    """Index of the nearest real vessel node of every node. Jittable.

    Args:
        x: ``[N, 3]`` positions. node_type: ``[N]`` NodeType. mask: ``[N]`` real nodes.
        block: query rows per pass (memory ``block x N``).
    Returns:
        ``[N]`` int32 indices (0 for every node when there is no real vessel node).
    """
    n = x.shape[0]
    vessel = jnp.asarray(mask, bool) & (jnp.asarray(node_type) == NodeType.VESSEL)
    sq = jnp.sum(x * x, axis=-1)
    far = jnp.where(vessel, 0.0, jnp.inf)

    def rows(q: jax.Array) -> jax.Array:
        d2 = jnp.sum(q * q, axis=-1)[:, None] + sq[None, :] - 2.0 * q @ x.T + far[None, :]
        return jnp.argmin(d2, axis=1).astype(jnp.int32)

    if n <= block:
        return rows(x)
    n_blocks = -(-n // block)
    padded = jnp.pad(x, ((0, n_blocks * block - n), (0, 0)))
    return jax.lax.map(rows, padded.reshape(n_blocks, block, 3)).reshape(-1)[:n]


def wall_node_features(
    x: jax.Array, node_type: jax.Array, mask: jax.Array, *, cutoff: float
) -> jax.Array:
    """Distance and direction to the nearest vessel node, clipped at ``cutoff``. Jittable.

    Args:
        x: ``[N, 3]`` positions (gradients are stopped: these are inputs, like the graph).
        node_type: ``[N]`` NodeType. mask: ``[N]`` real nodes.
        cutoff: distance beyond which the wall is not felt (> 0, units of ``x``).
    Returns:
        ``[N, 4]``: ``min(d, cutoff) / cutoff`` and the unit vector from the node to its nearest
        vessel node times ``d < cutoff``, on real clot nodes; zeros on every other node.
    """
    if not cutoff > 0:
        raise ValueError(f"wall features: cutoff must be > 0, got {cutoff!r}")
    x = jax.lax.stop_gradient(x)
    j = nearest_vessel_node(x, node_type, mask)
    feats = clipped_distance_direction(x[j] - x, cutoff)
    has_wall = jnp.any(jnp.asarray(mask, bool) & (jnp.asarray(node_type) == NodeType.VESSEL))
    keep = clot_mask(node_type, mask) & has_wall
    return jnp.where(keep[:, None], feats, 0.0)
