"""Model inputs that generalise across vessels and orientations, and the outside-wall measure.

(The rest-state edge displacements of DeepMind's deforming-plate MeshGraphNet are the model's
own edge input: ``thrombojax.models.meshgraphnet.edge_features``, for ``rest_edges``.)

* :func:`wall_features`: per node the distance and unit direction to its nearest wall point
  (:func:`thrombojax.simulator.wall.nearest_wall_point`), cut off at a radius: ``[min(d, cutoff)
  / cutoff, direction * (d < cutoff)]``. Distances are invariant and directions rotate with the
  vessel, like the relative displacements a graph network already sees.
* :func:`fraction_outside_wall`: the fraction of clot nodes outside the wall, under ``jit``
  (the same outside test as :func:`thrombojax.simulator.guards.contain`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.graph.wall_nodes import clipped_distance_direction
from thrombojax.simulator.wall import Wall, nearest_wall_point

__all__ = ["WALL_FEATURES", "wall_features", "fraction_outside_wall"]

WALL_FEATURES: int = 4
"""Width of :func:`wall_features`: clipped distance / cutoff and a 3-D direction."""


def wall_features(
    x: jax.Array, wall: Wall, *, cutoff: float, node_mask: jax.Array | None = None
) -> jax.Array:
    """Distance and direction to the nearest wall point, clipped at ``cutoff``. Jittable.

    Args:
        x: ``[N, 3]`` positions (the wall's coordinates).
        wall: the :class:`~thrombojax.simulator.wall.Wall`.
        cutoff: radius beyond which the wall is not felt (> 0, same units as ``x``).
        node_mask: ``[N]`` bool, nodes that get features (others get zeros); None: all.
    Returns:
        ``[N, 4]``: ``min(d, cutoff) / cutoff`` (1 far from the wall) and the unit vector from
        the node to its nearest wall point times ``d < cutoff`` (zero when ``d`` is 0).
    """
    feats = clipped_distance_direction(nearest_wall_point(x, wall).point - x, cutoff)
    if node_mask is not None:
        feats = jnp.where(node_mask[:, None], feats, 0.0)
    return feats


def fraction_outside_wall(
    x: jax.Array, clot_mask: jax.Array, wall: Wall, *, tol: float = 0.0
) -> jax.Array:
    """Fraction of clot nodes outside the wall (beyond ``slack + tol``, not past an open end).

    Args:
        x: ``[N, 3]`` positions.
        clot_mask: ``[N]`` bool, the nodes that count.
        wall: the :class:`~thrombojax.simulator.wall.Wall`.
        tol: extra signed distance tolerated (e.g. the solver's contact penetration).
    Returns:
        ``[]`` float in [0, 1] (0 when there is no clot node).
    """
    q = nearest_wall_point(x, wall)
    out = clot_mask & (q.signed > q.slack + tol) & ~q.past_end
    return jnp.sum(out) / jnp.maximum(jnp.sum(clot_mask), 1)

