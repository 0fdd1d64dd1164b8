"""Fixed-capacity radius graphs under ``jax.jit``: dense tiled all-pairs and a cell grid.

Conventions (every model relies on them):

* ``NeighborList.indices[i]`` lists the neighbours ``j`` of node ``i``: the ``K = max_neighbors``
  *nearest* nodes with ``|x_i - x_j| < r`` (strict), sorted by distance, nearest first (exact
  ties: Morton order for the dense method, cell order for the grid).
  Empty slots hold the sentinel ``N`` (``N`` = number of rows, padding included).
* Cap semantics: like torch_cluster's ``max_num_neighbors`` a node keeps at most ``K`` neighbours,
  but torch_cluster keeps the *first K found* (search order) while we keep the *K nearest*. The
  cap is the model's definition, not an error: ``counts`` tells how many there were before it.
* ``loop=False`` (default) excludes ``j == i``; distinct nodes at distance 0 are neighbours.
* Padded nodes (``mask[i]`` False) have no neighbours (row all sentinel, ``counts`` 0) and are
  in no list.
* ``overflow`` is raised only when a fixed buffer could have hidden a neighbour (grid method): the
  result may then be wrong and the caller must re-allocate (:func:`radius_graph_checked`). The
  dense method never overflows.
* Edges for message passing: sender ``j`` (the neighbour) -> receiver ``i``. In
  :func:`senders_receivers` a sentinel edge has sender = receiver = ``N``, so a
  ``segment_sum(..., num_segments=N)`` drops it and with one dummy node appended it lands there.

Methods: ``"dense"`` compares each row tile with all nodes (``lax.map`` over tiles of
``tile_rows`` rows; peak memory ``tile_rows x N``, never ``N x N``) and selects the K nearest
exactly among the nearest Morton blocks of nodes (:mod:`thrombojax.graph.dense`); ``"grid"``
hashes nodes into cells (see :class:`GridSpec`) and compares each node with the nodes of its
27 surrounding cells only; ``"auto"`` picks ``"grid"`` when a :class:`GridSpec` is given,
``N >= AUTO_GRID_MIN_NODES`` and the grid examines at most half as many candidates as the dense
method (about ``9 * capacity`` per node against ``N``), else ``"dense"``.

CPU speed (``benchmarks/graphs.py``, recorded in ``benchmarks/results/graphs_cpu.json``; 2
cores, study radii, K = 32): dense ~9-11 ms at N = 2,048; at N = 27,000 the grid ~0.25 s, the
dense method ~0.5 s.
"""

from __future__ import annotations

from typing import Literal

import jax
import jax.numpy as jnp
import jraph
import numpy as np
from flax import struct

from thrombojax.errors import CapacityOverflowError, ConfigError
from thrombojax.graph.capacity import estimate_capacity, grow
from thrombojax.graph.dense import dense_search
from thrombojax.graph.grid import GridSpec, _has_heavy, grid_search

__all__ = [
    "AUTO_GRID_MIN_NODES",
    "NeighborList",
    "GridSpec",
    "radius_graph",
    "radius_graph_checked",
    "allocate",
    "estimate_capacity",
    "senders_receivers",
    "edge_mask",
    "edge_displacements",
    "to_graphs_tuple",
    "graph_overflow",
]

AUTO_GRID_MIN_NODES: int = 4096
"""``method="auto"`` uses the grid only from this many nodes on (below, dense is as fast)."""


@struct.dataclass
class NeighborList:
    """Fixed-capacity neighbour list of one frame (a pytree).

    Attributes:
        indices: ``[N, K]`` int32 neighbour indices, nearest first, sentinel ``N`` in empty slots.
        counts: ``[N]`` int32 number of neighbours within ``r`` before the cap ``K``.
        overflow: ``[]`` bool, True if a fixed buffer overflowed (result unreliable: re-allocate).
    """

    indices: jax.Array
    counts: jax.Array
    overflow: jax.Array

    @property
    def n_nodes(self) -> int:
        return self.indices.shape[-2]

    @property
    def max_neighbors(self) -> int:
        return self.indices.shape[-1]


def _grid_pays(grid: GridSpec | None, n: int) -> bool:
    """The grid is worth it when it examines at most half the candidates of the dense method."""
    if grid is None or n < AUTO_GRID_MIN_NODES:
        return False
    h = min(grid.heavy_nodes, n) if _has_heavy(grid) else 0
    return 9 * ((n - h) * grid.capacity + h * grid.heavy_capacity) <= n * n // 2


def _dense(positions, r, k, mask, loop, tile_rows):
    ids, counts, _ = dense_search(positions, r, k, mask, loop, tile_rows)
    return NeighborList(indices=ids, counts=counts, overflow=jnp.zeros((), bool))


def radius_graph(
    positions: jax.Array,
    r: float,
    max_neighbors: int,
    *,
    mask: jax.Array | None = None,
    loop: bool = False,
    method: Literal["auto", "dense", "grid"] = "auto",
    grid: GridSpec | None = None,
    tile_rows: int | None = None,
) -> NeighborList:
    """The K nearest neighbours within ``r`` of every node, with a fixed capacity. Jittable.

    See the module docstring for the conventions (nearest first, sentinel ``N``, cap semantics,
    masks, overflow). ``r``, ``max_neighbors``, ``loop``, ``method``, ``grid`` and ``tile_rows``
    must be static under jit.

    Args:
        positions: ``[N, 3]`` float node positions.
        r: radius; ``j`` is a neighbour of ``i`` iff ``|x_i - x_j| < r``.
        max_neighbors: capacity ``K`` per node (the study uses 32).
        mask: ``[N]`` bool, True for real nodes (default all real).
        loop: include ``i`` in its own list (it counts in ``counts`` too).
        method: ``"dense"``, ``"grid"`` (needs ``grid``) or ``"auto"``.
        grid: the :class:`GridSpec` (from :func:`thrombojax.graph.estimate_capacity`).
        tile_rows: dense method: rows per tile (default: ``tile_rows * N <= 2**19``, at least 16).

    Returns:
        A :class:`NeighborList` with ``indices [N, K]``, ``counts [N]``, ``overflow []``.
    """
    positions = jnp.asarray(positions)
    n = positions.shape[0]
    if mask is None:
        mask = jnp.ones((n,), bool)
    mask = jnp.asarray(mask, bool)
    if method == "auto":
        method = "grid" if _grid_pays(grid, n) else "dense"
    if method == "dense":
        return _dense(positions, r, max_neighbors, mask, loop, tile_rows)
    if method == "grid":
        if grid is None:
            raise ConfigError("radius_graph(method='grid') needs a GridSpec: see estimate_capacity")
        ids, counts, overflow = grid_search(positions, r, max_neighbors, mask, loop, grid)
        return NeighborList(indices=ids, counts=counts, overflow=overflow)
    raise ConfigError(f"unknown radius_graph method {method!r}: use 'auto', 'dense' or 'grid'")


def graph_overflow(graph) -> jax.Array:
    """``[]`` bool: whether any :class:`NeighborList` inside the pytree ``graph`` overflowed.

    Works on any model graph (a neighbour list, Erwin's tree plus neighbour list, an empty
    graph: False). Jittable.
    """
    flags = [
        jnp.any(leaf.overflow)
        for leaf in jax.tree_util.tree_leaves(graph, is_leaf=lambda x: isinstance(x, NeighborList))
        if isinstance(leaf, NeighborList)
    ]
    return jnp.any(jnp.stack(flags)) if flags else jnp.zeros((), bool)


def senders_receivers(nbrs: NeighborList) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Flatten a neighbour list into edges ``j -> i`` (row-major: edge ``i*K + s``).

    Args:
        nbrs: neighbour list with ``indices [N, K]``.

    Returns:
        ``senders [N*K]`` int32 (the neighbour ``j``), ``receivers [N*K]`` int32 (the node ``i``)
        and ``edge_mask [N*K]`` bool. Sentinel edges have sender = receiver = ``N``.
    """
    n, k = nbrs.indices.shape
    senders = nbrs.indices.reshape(-1)
    valid = senders < n
    receivers = jnp.repeat(jnp.arange(n, dtype=jnp.int32), k)
    return senders, jnp.where(valid, receivers, n), valid


def edge_mask(nbrs: NeighborList) -> jax.Array:
    """``[N*K]`` bool: True for real edges (same order as :func:`senders_receivers`)."""
    return nbrs.indices.reshape(-1) < nbrs.indices.shape[0]


def edge_displacements(positions: jax.Array, nbrs: NeighborList) -> tuple[jax.Array, jax.Array]:
    """Relative positions of the edges: ``x_receiver - x_sender`` and its norm, 0 on sentinels.

    Args:
        positions: ``[N, 3]``.
        nbrs: neighbour list of these positions.

    Returns:
        ``dx [N*K, 3]`` (``x_i - x_j``) and ``dist [N*K, 1]``.
    """
    n, k = nbrs.indices.shape
    valid = nbrs.indices < n
    xj = positions[jnp.minimum(nbrs.indices, n - 1)]
    dx = jnp.where(valid[..., None], positions[:, None, :] - xj, 0.0).reshape(n * k, 3)
    return dx, jnp.sqrt(jnp.sum(dx * dx, axis=-1, keepdims=True))


def to_graphs_tuple(
    nbrs: NeighborList,
    node_features: jax.Array,
    edge_features: jax.Array | None = None,
    globals_: jax.Array | None = None,
) -> jraph.GraphsTuple:
    """A padded ``jraph.GraphsTuple`` of one graph plus one dummy node and one padding graph.

    Layout: ``nodes [N+1, F]`` (row ``N`` is the zero dummy node), ``senders``/``receivers``
    ``[N*K]`` from :func:`senders_receivers` (sentinel edges point from and to the dummy node, so
    jraph's segment sums put their messages there), ``n_node = [N, 1]``,
    ``n_edge = [E_real, N*K - E_real]``. Real and sentinel edges are interleaved, so use
    :func:`edge_mask` (not ``jraph.get_edge_padding_mask``) to mask edge quantities.

    Args:
        nbrs: neighbour list ``[N, K]``.
        node_features: ``[N, F]``.
        edge_features: optional ``[N*K, E]`` (e.g. from :func:`edge_displacements`).
        globals_: optional ``[2, G]`` globals (default none).

    Returns:
        The ``jraph.GraphsTuple``.
    """
    n = nbrs.indices.shape[0]
    senders, receivers, valid = senders_receivers(nbrs)
    nodes = jnp.concatenate(
        [node_features, jnp.zeros((1,) + node_features.shape[1:], node_features.dtype)], axis=0
    )
    e_real = jnp.sum(valid, dtype=jnp.int32)
    return jraph.GraphsTuple(
        nodes=nodes,
        edges=edge_features,
        senders=senders,
        receivers=receivers,
        globals=globals_,
        n_node=jnp.array([n, 1], jnp.int32),
        n_edge=jnp.stack([e_real, senders.shape[0] - e_real]),
    )


_radius_graph_jit = jax.jit(
    radius_graph, static_argnames=("r", "max_neighbors", "loop", "method", "grid", "tile_rows")
)


def radius_graph_checked(
    positions,
    r: float,
    max_neighbors: int,
    *,
    mask=None,
    loop: bool = False,
    method: Literal["auto", "dense", "grid"] = "auto",
    grid: GridSpec | None = None,
    max_retries: int = 4,
    growth: float = 2.0,
) -> tuple[NeighborList, GridSpec | None]:
    """Host wrapper: build the graph (jitted) and re-allocate on overflow, never truncate.

    On overflow the grid is grown (:func:`thrombojax.graph.capacity.grow`) and the graph rebuilt, up
    to ``max_retries`` times; a grid search that still overflows falls back to the dense method
    when ``method="auto"``.

    Args:
        positions: ``[N, 3]`` one frame (host or device array).
        r, max_neighbors, mask, loop, method, grid: as in :func:`radius_graph`.
        max_retries: re-allocations allowed before giving up.
        growth: capacity factor per re-allocation.

    Returns:
        ``(nbrs, grid)``: an overflow-free :class:`NeighborList` and the spec that produced it
        (pass it to the next call / to the jitted rollout).

    Raises:
        CapacityOverflowError: if the grid still overflows after ``max_retries`` re-allocations.
    """
    if method == "grid" and grid is None:
        grid = estimate_capacity(positions, r, max_neighbors, mask=mask, loop=loop)
    for _ in range(max_retries + 1):
        nbrs = _radius_graph_jit(
            positions, r, max_neighbors, mask=mask, loop=loop, method=method, grid=grid
        )
        if not bool(nbrs.overflow):
            return nbrs, grid
        grid = grow(grid, r, growth)
    if method == "auto":
        return _radius_graph_jit(positions, r, max_neighbors, mask=mask, loop=loop), None
    raise CapacityOverflowError(
        f"radius_graph: grid still overflows after {max_retries} re-allocations "
        f"(last GridSpec {grid}, N={len(positions)}, r={r}, max_neighbors={max_neighbors})"
    )


def allocate(
    positions,
    r: float,
    max_neighbors: int,
    *,
    mask=None,
    loop: bool = False,
    method: Literal["auto", "dense", "grid"] = "auto",
    margin: float = 1.25,
) -> tuple[NeighborList, GridSpec | None]:
    """Size the buffers from data and build a first, checked neighbour list (host side).

    Args:
        positions: ``[N, 3]`` or ``[F, N, 3]`` example frames (the graph is built for the last).
        r, max_neighbors, mask, loop: as in :func:`radius_graph`.
        method: ``"dense"`` needs no spec (returns ``None``); ``"grid"`` always sizes one;
            ``"auto"`` sizes one when ``N >= AUTO_GRID_MIN_NODES`` and keeps it if it pays.
        margin: safety factor of :func:`estimate_capacity`.

    Returns:
        ``(nbrs, grid)`` as :func:`radius_graph_checked`.
    """
    frames = np.asarray(positions)
    n = frames.shape[-2]
    grid = None
    if method == "grid" or (method == "auto" and n >= AUTO_GRID_MIN_NODES):
        grid = estimate_capacity(frames, r, max_neighbors, mask=mask, loop=loop, margin=margin)
        grid = grid if method == "grid" or _grid_pays(grid, n) else None
    last = frames if frames.ndim == 2 else frames[-1]
    last_mask = None if mask is None else np.asarray(mask).reshape(-1, n)[-1]
    return radius_graph_checked(
        last, r, max_neighbors, mask=last_mask, loop=loop, method=method, grid=grid
    )
