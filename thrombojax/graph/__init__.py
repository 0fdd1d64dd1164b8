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
from thrombojax.graph.capacity import estimate_capacity, grow
from thrombojax.graph.grid import GridSpec
from thrombojax.graph.neighbors import (
    AUTO_GRID_MIN_NODES,
    NeighborList,
    allocate,
    edge_displacements,
    edge_mask,
    radius_graph,
    radius_graph_checked,
    senders_receivers,
    to_graphs_tuple,
)
from thrombojax.graph.triangles import find_triangles

__all__ = [
    "AUTO_GRID_MIN_NODES",
    "BallTree",
    "GridSpec",
    "NeighborList",
    "allocate",
    "build_balltree",
    "build_balltree_numpy",
    "default_num_slots",
    "edge_displacements",
    "edge_mask",
    "estimate_capacity",
    "find_triangles",
    "grow",
    "level_sizes",
    "radius_graph",
    "radius_graph_checked",
    "rotated_partitions",
    "rotation_matrix",
    "senders_receivers",
    "to_graphs_tuple",
]
