"""Cell-grid neighbour search with fixed capacities (jittable).

The grid follows jax-md's allocate / update split:
:func:`thrombojax.graph.capacity.estimate_capacity` (host, numpy + scipy) sizes a
:class:`GridSpec` from example frames; :func:`grid_search` (jit) uses it with
static shapes and raises an overflow flag whenever a buffer was too small to guarantee the
exact answer, so the caller re-allocates (see ``thrombojax.graph.neighbors``).

Layout: cell ``(cx, cy, cz)`` of side ``h`` has linear id ``cx + nx * (cy + ny * cz)``, so the
3 cells ``cx-1..cx+1`` of one (cy, cz) row are consecutive in id order. After sorting the nodes
by cell id, the neighbourhood of a node is 9 *runs* of consecutive sorted nodes; each run is read
into ``capacity`` candidate slots. A run longer than ``capacity`` raises ``overflow``.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.errors import ConfigError

__all__ = ["GridSpec", "grid_search", "smallest_k"]

_TILE_ELEMENTS = 1 << 13  # small tiles stay in cache (measured: 2**13 ~1.5x faster than 2**15)
_TWO_STAGE_MIN = 8192  # rows at least this long select in two stages (measured: 2x at 27,000)
_MAX_CELLS_PER_AXIS = 1290  # cell ids stay below 2**31 (beyond: border cells crowd -> overflow)


@dataclasses.dataclass(frozen=True)
class GridSpec:
    """Static shape of the cell grid (hashable, so it can be a static jit argument).

    The grid's origin is the minimum corner of the real nodes (computed inside jit); cells are
    cubes of side ``cell_size`` and there are ``grid_shape`` cells per axis; coordinates beyond
    the last cell are clamped into it (this only crowds border cells, and crowding is caught
    by the overflow flag). A node's candidates are its 9 *runs* (3 x-consecutive cells per
    (y, z) row around it). Vessel clouds are very uneven (a dense clot inside a sparse wall), so
    the nodes are split by their largest run: all but ``heavy_nodes`` read ``capacity`` slots
    per run, the ``heavy_nodes`` nodes with the largest runs read ``heavy_capacity`` slots.

    With ``cell_size >= r`` every node within ``r`` is examined (counts exact). With
    ``cell_size < r`` (k-nearest mode, for large radii) only nodes within ``cell_size`` are
    guaranteed to be examined: the K nearest are still exact iff the K-th nearest neighbour of
    each real node lies within ``cell_size``; otherwise ``overflow`` is raised. In this mode
    ``counts`` is the number of neighbours within ``cell_size``: a lower bound of the count
    within ``r``, ``>= K`` (cap hit) whenever there is no overflow. In k-nearest mode the heavy
    nodes may search a second, finer grid (``heavy_cell_size > 0``): the same guarantee holds
    with that grid's cell size for them (their ``counts`` are within it).

    Attributes:
        cell_size: side of a cell (units of the positions).
        grid_shape: ``(nx, ny, nz)`` cells per axis (each >= 1).
        capacity: slots per run for the light nodes.
        heavy_capacity: slots per run for the heavy nodes (``>= capacity`` on this grid).
        heavy_nodes: number of nodes searched with ``heavy_capacity`` (0: none).
        heavy_cell_size: k-nearest mode only: if > 0, the heavy nodes (dense regions) search a
            second, finer grid of this cell size (their K-th neighbour is closer), with
            ``heavy_capacity`` slots per run of that grid; 0: the same grid as the light nodes.
        heavy_grid_shape: cells per axis of that finer grid.
    """

    cell_size: float
    grid_shape: tuple[int, int, int]
    capacity: int
    heavy_capacity: int = 0
    heavy_nodes: int = 0
    heavy_cell_size: float = 0.0
    heavy_grid_shape: tuple[int, int, int] = (1, 1, 1)

    def heavy_spec(self) -> GridSpec:
        """The grid searched by the heavy nodes (this one, or the finer second grid)."""
        if self.heavy_cell_size <= 0:
            return self
        return GridSpec(self.heavy_cell_size, self.heavy_grid_shape, self.heavy_capacity)


def smallest_k(d2: jax.Array, k: int) -> tuple[jax.Array, jax.Array]:
    """The ``k`` smallest entries of each row of ``d2 [T, M]``, ascending, exactly.

    Equals ``lax.top_k(-d2, k)`` up to the order of exactly equal values. Rows shorter than
    ``_TWO_STAGE_MIN`` use ``lax.top_k`` directly; longer rows (``lax.top_k`` costs about ``M``
    per row on the CPU) are cut into ``B`` *strided* blocks of ``s ~ sqrt(M / k)`` columns
    (block ``b`` holds columns ``b, b + B, ...``, so a spatially coherent node order spreads
    over the blocks): ``top_k`` of the ``B`` block minima picks ``k`` blocks, then ``top_k`` of
    their ``k * s`` entries. Exact: each of the ``k`` smallest entries lies in a block whose
    minimum is at most the ``k``-th smallest block minimum, i.e. in a chosen block (a tie at the
    ``k``-th value may swap it for an equal value).

    Returns:
        ``(values [T, k], positions [T, k] int32)``, ``inf`` values past a row's finite entries.
    """
    t, m = d2.shape
    if m < _TWO_STAGE_MIN:
        neg, pos = jax.lax.top_k(-d2, k)
        return -neg, pos.astype(jnp.int32)
    s = max(2, round(math.sqrt(m / k)))
    nb = -(-m // s)
    blocks = jnp.pad(d2, ((0, 0), (0, nb * s - m)), constant_values=jnp.inf).reshape(t, s, nb)
    _, bsel = jax.lax.top_k(-jnp.min(blocks, axis=1), min(k, nb))
    kb = bsel.shape[1]
    vals = jnp.take_along_axis(blocks, jnp.broadcast_to(bsel[:, None, :], (t, s, kb)), axis=2)
    cols = bsel[:, None, :] + nb * jnp.arange(s, dtype=bsel.dtype)[None, :, None]
    neg, pos = jax.lax.top_k(-vals.reshape(t, s * kb), k)
    pos = jnp.take_along_axis(cols.reshape(t, s * kb), pos, axis=1)
    return -neg, jnp.minimum(pos, m - 1).astype(jnp.int32)  # padding columns hold inf only


def _cells(positions, mask, spec):
    """Integer cell coordinates ``[N, 3]`` (clamped) and linear ids ``[N]`` (padding: ``M``)."""
    xp = jnp if isinstance(positions, jax.Array) else np
    shape = xp.asarray(spec.grid_shape)
    lo = xp.min(xp.where(mask[:, None], positions, xp.inf), axis=0)
    c = xp.floor((positions - lo) / spec.cell_size)
    c = xp.clip(xp.where(xp.isfinite(c), c, 0), 0, shape - 1).astype(xp.int32)
    nx, ny, nz = spec.grid_shape
    cid = c[:, 0] + nx * (c[:, 1] + ny * c[:, 2])
    return c, xp.where(mask, cid, nx * ny * nz)


def _runs(c, spec, np_mod=jnp):
    """Per node, the first/last cell id of its 9 x-runs ``[N, 9]`` and their validity."""
    nx, ny, nz = spec.grid_shape
    d = np_mod.array([(dy, dz) for dz in (-1, 0, 1) for dy in (-1, 0, 1)], np_mod.int32)
    cy = c[:, 1:2] + d[None, :, 0]
    cz = c[:, 2:3] + d[None, :, 1]
    ok = (cy >= 0) & (cy < ny) & (cz >= 0) & (cz < nz)
    row = nx * (cy + ny * cz)
    first = row + np_mod.maximum(c[:, 0:1] - 1, 0)
    last = row + np_mod.minimum(c[:, 0:1] + 1, nx - 1)
    return first, last, ok


def _query_runs(positions, mask, spec, xp):
    """Nodes sorted by cell and, per sorted node, its 9 runs as sorted-position ranges."""
    c, cid = _cells(positions, mask, spec)
    order = xp.argsort(cid, stable=True).astype(xp.int32)
    sorted_cid = cid[order]
    first, last, ok = _runs(c[order], spec, xp)
    start = xp.searchsorted(sorted_cid, first.reshape(-1), side="left").reshape(first.shape)
    end = xp.searchsorted(sorted_cid, last.reshape(-1), side="right").reshape(first.shape)
    live = ok & mask[order][:, None]  # real query and a row inside the grid
    return order, start.astype(xp.int32), xp.where(live, end, start).astype(xp.int32), live


def _search(positions, order, start, end, queries, r, k, loop, cap, cell_size):
    """K nearest for the sorted-order ``queries [Q]`` reading ``cap`` slots per run."""
    n = positions.shape[0]
    r2 = jnp.asarray(r, positions.dtype) ** 2
    h2 = jnp.asarray(cell_size, positions.dtype) ** 2
    knn_mode = cell_size < r
    width = 9 * cap
    kk = min(k, width)
    run = np.arange(width) // cap
    off = jnp.arange(width, dtype=jnp.int32) % cap
    cols = tuple(jnp.pad(positions[order], ((0, cap), (0, 0))).T)  # 3 x [N + cap]

    def one(args):  # one query: sorted position, its own runs [9] as [start, end)
        q, s, e = args
        d2 = 0.0
        for col in cols:  # per coordinate: contiguous windows, vectorised differences
            win = jax.vmap(lambda s0, col=col: jax.lax.dynamic_slice(col, (s0,), (cap,)))(s)
            d2 = d2 + (col[q] - win.reshape(width)) ** 2
        cand = s[run] + off
        okc = (cand < e[run]) & (d2 < r2)
        if knn_mode:  # beyond the cell size a node cannot be among the K nearest (else: miss)
            okc = okc & (d2 <= h2)
        if not loop:
            okc = okc & (cand != q)
        return jnp.where(okc, -d2, -jnp.inf), cand, jnp.sum(okc, dtype=jnp.int32)

    def tile(args):
        neg, cand, counts = jax.vmap(one)(args)
        vals, pos = smallest_k(-neg, kk)
        found = jnp.isfinite(vals)
        ids = jnp.where(found, order[jnp.take_along_axis(cand, pos, 1) % n], n)
        real = args[2][:, 0] >= 0
        miss = real & ((kk < k) | ~found[:, kk - 1]) if knn_mode else jnp.zeros_like(real)
        return ids.astype(jnp.int32), counts, miss

    t = max(1, min(queries.shape[0], _TILE_ELEMENTS // width))
    pad = (-queries.shape[0]) % t
    qs = jnp.pad(queries, (0, pad))
    xs = (
        qs,
        jnp.pad(start[queries], ((0, pad), (0, 0))),
        jnp.pad(end[queries], ((0, pad), (0, 0)), constant_values=-1),
    )
    xs = tuple(a.reshape((-1, t) + a.shape[1:]) for a in xs)
    ids, counts, miss = jax.lax.map(tile, xs)
    q = queries.shape[0]
    return ids.reshape(-1, kk)[:q], counts.reshape(-1)[:q], jnp.any(miss)


def grid_search(positions, r, k, mask, loop, spec: GridSpec):
    """Jittable grid search; see :func:`thrombojax.graph.radius_graph` for the conventions.

    Nodes are sorted by cell; each query gathers its 9 runs as contiguous windows of the sorted
    cloud. Queries are ordered by their largest run: the light ones read ``spec.capacity``
    slots per run, the last ``spec.heavy_nodes`` read ``spec.heavy_capacity``.

    Args:
        positions: ``[N, 3]``; r, k: radius and cap; mask: ``[N]`` bool; loop: keep ``i -> i``.
        spec: the :class:`GridSpec`.

    Returns:
        ``indices [N, k]`` int32 (nearest first, sentinel N), ``counts [N]`` int32,
        ``overflow []`` bool.
    """
    n = positions.shape[0]
    _check_shape(spec)
    order, start, end, live = _query_runs(positions, mask, spec, jnp)
    real = mask[order]
    end = jnp.where(real[:, None], end, -1)  # padded queries: no candidates
    weight = jnp.max(jnp.where(live, end - start, 0), axis=1)
    n_heavy = min(spec.heavy_nodes, n) if _has_heavy(spec) else 0
    by_weight = jnp.argsort(weight, stable=True).astype(jnp.int32)
    light, heavy = by_weight[: n - n_heavy], by_weight[n - n_heavy :]
    overflow = jnp.any(weight[light] > spec.capacity)
    ids, counts, miss = _search(
        positions, order, start, end, light, r, k, loop, spec.capacity, spec.cell_size
    )
    if n_heavy and spec.heavy_cell_size > 0:  # the heavy nodes search the finer grid
        fine = spec.heavy_spec()
        _check_shape(fine)
        order_f, start_f, end_f, live_f = _query_runs(positions, mask, fine, jnp)
        end_f = jnp.where(mask[order_f][:, None], end_f, -1)
        rank_f = jnp.zeros((n,), jnp.int32).at[order_f].set(jnp.arange(n, dtype=jnp.int32))
        heavy_f = rank_f[order[heavy]]  # the heavy nodes' positions in the fine sorted order
        weight_f = jnp.max(jnp.where(live_f, end_f - start_f, 0), axis=1)
        overflow |= jnp.any(weight_f[heavy_f] > spec.heavy_capacity)
        ids_h, counts_h, miss_h = _search(
            positions, order_f, start_f, end_f, heavy_f, r, k, loop, fine.capacity, fine.cell_size
        )
    elif n_heavy:
        overflow |= jnp.any(weight[heavy] > spec.heavy_capacity)
        ids_h, counts_h, miss_h = _search(
            positions, order, start, end, heavy, r, k, loop, spec.heavy_capacity, spec.cell_size
        )
    if n_heavy:
        ids = jnp.concatenate([ids, ids_h])
        counts = jnp.concatenate([counts, counts_h])
        miss |= miss_h
    node = order[by_weight]  # node id of each processed query
    indices = jnp.zeros((n, k), jnp.int32).at[node].set(_pad_cols(ids, k, n))
    return indices, jnp.zeros((n,), jnp.int32).at[node].set(counts), overflow | miss


def _has_heavy(spec: GridSpec) -> bool:
    """Whether the heavy nodes are searched apart (larger capacity or a finer grid)."""
    return spec.heavy_nodes > 0 and (
        spec.heavy_capacity > spec.capacity or spec.heavy_cell_size > 0
    )


def _check_shape(spec: GridSpec) -> None:
    if math.prod(spec.grid_shape) >= 2**31 - 1 or min(spec.grid_shape) < 1:
        raise ConfigError(f"GridSpec.grid_shape {spec.grid_shape}: need 1 <= cells < 2**31")


def _pad_cols(ids, k, n):
    return (
        ids
        if ids.shape[1] == k
        else jnp.pad(ids, ((0, 0), (0, k - ids.shape[1])), constant_values=n)
    )
