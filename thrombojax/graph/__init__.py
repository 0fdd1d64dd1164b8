"""Graph structure built from positions inside ``jax.jit``: radius graphs, Erwin ball trees,
triangles. See :mod:`thrombojax.graph.neighbors` and :mod:`thrombojax.graph.balltree` for the
exact conventions (sentinels, padding, orderings)."""

from thrombojax.graph.balltree import (
    BallTree,
    build_balltree,
    build_balltree_numpy,
    default_num_slots,
    level_sizes,
    rotated_partitions,
    rotation_matrix,
)
from thrombojax.graph.neighbors import (
    AUTO_GRID_MIN_NODES,
    GridSpec,
    NeighborList,
    edge_displacements,
    edge_mask,
    radius_graph,
    senders_receivers,
    to_graphs_tuple,
)

__all__ = [
    "AUTO_GRID_MIN_NODES",
    "BallTree",
    "GridSpec",
    "NeighborList",
    "build_balltree",
    "build_balltree_numpy",
    "default_num_slots",
    "edge_displacements",
    "edge_mask",
    "level_sizes",
    "radius_graph",
    "rotated_partitions",
    "rotation_matrix",
    "senders_receivers",
    "to_graphs_tuple",
]
