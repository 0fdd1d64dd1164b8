"""Cell-grid neighbour search with fixed capacities (jittable) and its host-side sizing.

The grid follows jax-md's allocate / update split: :func:`estimate_capacity` (host, numpy +
scipy) sizes a :class:`GridSpec` from example frames; :func:`grid_search` (jit) uses it with
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
from scipy.spatial import cKDTree

__all__ = ["GridSpec", "grid_search", "estimate_capacity", "grow"]

_TILE_ELEMENTS = 1 << 20


@dataclasses.dataclass(frozen=True)
class GridSpec:
    """Static shape of the cell grid (hashable, so it can be a static jit argument).

    The grid's origin is the minimum corner of the real nodes (computed inside jit); cells are
    cubes of side ``cell_size`` and there are ``grid_shape`` cells per axis; coordinates beyond
    the last cell are clamped into it (this only crowds border cells, and crowding is caught
    by the overflow flag). ``capacity`` bounds the number of nodes in one run of 3 x-consecutive
    cells.

    With ``cell_size >= r`` every node within ``r`` is examined (counts exact). With
    ``cell_size < r`` (k-nearest mode, for large radii) only nodes within ``cell_size`` are
    guaranteed to be examined: the K nearest are still exact iff the K-th nearest neighbour of
    each real node lies within ``cell_size``; otherwise ``overflow`` is raised. In this mode
    ``counts`` is the number of neighbours within ``cell_size``: a lower bound of the count
    within ``r``, ``>= K`` (cap hit) whenever there is no overflow.

    Attributes:
        cell_size: side of a cell (units of the positions).
        grid_shape: ``(nx, ny, nz)`` cells per axis (each >= 1).
        capacity: slots per run of 3 x-consecutive cells.
    """

    cell_size: float
    grid_shape: tuple[int, int, int]
    capacity: int


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


def grid_search(positions, r, k, mask, loop, spec: GridSpec):
    """Jittable grid search; see :func:`thrombojax.graph.radius_graph` for the conventions.

    Args:
        positions: ``[N, 3]``; r, k: radius and cap; mask: ``[N]`` bool; loop: keep ``i -> i``.
        spec: the :class:`GridSpec`.

    Returns:
        ``indices [N, k]`` int32 (nearest first, sentinel N), ``counts [N]`` int32,
        ``overflow []`` bool.
    """
    n = positions.shape[0]
    cap = spec.capacity
    c, cid = _cells(positions, mask, spec)
    order = jnp.argsort(cid).astype(jnp.int32)
    sorted_cid = cid[order]
    first, last, ok = _runs(c, spec)
    start = jnp.searchsorted(sorted_cid, first, side="left").astype(jnp.int32)
    end = jnp.searchsorted(sorted_cid, last, side="right").astype(jnp.int32)
    end = jnp.where(ok, end, start)
    run_overflow = jnp.any(mask[:, None] & (end - start > cap))
    r2 = jnp.asarray(r, positions.dtype) ** 2
    h2 = jnp.asarray(spec.cell_size, positions.dtype) ** 2
    knn_mode = spec.cell_size < r
    width = 9 * cap
    kk = min(k, width)
    t = max(1, min(n, _TILE_ELEMENTS // width))
    n_tiles = -(-n // t)
    pad = n_tiles * t - n
    run = jnp.arange(width, dtype=jnp.int32) // cap
    off = jnp.arange(width, dtype=jnp.int32) % cap
    # everything below works on nodes sorted by cell: candidates are contiguous windows
    table = jnp.pad(positions[order], ((0, cap), (0, 0)))

    def windows(starts):  # [9] -> [9, cap, 3]
        return jax.vmap(lambda s0: jax.lax.dynamic_slice(table, (s0, 0), (cap, 3)))(starts)

    def tile(args):
        qpos, xq, real, s, e = args  # sorted positions [T], coords [T, 3], [T], runs [T, 9]
        xc = jax.vmap(windows)(s).reshape(-1, width, 3)
        diff = xq[:, None, :] - xc
        d2 = jnp.sum(diff * diff, axis=-1)
        cand = s[:, run] + off[None, :]
        okc = (cand < e[:, run]) & real[:, None] & (d2 < r2)
        if knn_mode:  # beyond the cell size a node cannot be among the K nearest (else: miss)
            okc = okc & (d2 <= h2)
        if not loop:
            okc = okc & (cand != qpos[:, None])
        neg, pos = jax.lax.top_k(jnp.where(okc, -d2, -jnp.inf), kk)
        found = jnp.isfinite(neg)
        ids = jnp.where(found, order[jnp.take_along_axis(cand, pos, 1) % n], n)
        miss = jnp.zeros(qpos.shape, bool)
        if knn_mode:  # exact only if the k-th neighbour lies within the cell size
            miss = real & ((kk < k) | ~found[:, kk - 1])
        return ids.astype(jnp.int32), jnp.sum(okc, 1, dtype=jnp.int32), miss

    def tiled(a, fill=0):
        a = jnp.pad(a, ((0, pad),) + ((0, 0),) * (a.ndim - 1), constant_values=fill)
        return a.reshape((n_tiles, t) + a.shape[1:])

    xs = (
        tiled(jnp.arange(n, dtype=jnp.int32)),
        tiled(table[:n]),
        tiled(mask[order], False),
        tiled(start[order]),
        tiled(end[order]),
    )
    ids, counts, miss = jax.lax.map(tile, xs)
    ids = ids.reshape(-1, kk)[:n]
    if kk < k:
        ids = jnp.pad(ids, ((0, 0), (0, k - kk)), constant_values=n)
    indices = jnp.zeros((n, k), jnp.int32).at[order].set(ids)
    counts = jnp.zeros((n,), jnp.int32).at[order].set(counts.reshape(-1)[:n])
    return indices, counts, run_overflow | jnp.any(miss)


def _kth_distance(points: np.ndarray, r: float, k: int, loop: bool) -> np.ndarray:
    """Distance to the k-th neighbour within r of each point (inf if fewer than k)."""
    kk = min(k + (0 if loop else 1), len(points))
    d, _ = cKDTree(points).query(points, k=kk, distance_upper_bound=r)
    d = d.reshape(len(points), kk)
    return d[:, -1] if kk == k + (0 if loop else 1) else np.full(len(points), np.inf)


def estimate_capacity(
    positions,
    r: float,
    max_neighbors: int,
    *,
    mask=None,
    loop: bool = False,
    cell_size: float | None = None,
    margin: float = 1.25,
    multiple: int = 8,
) -> GridSpec:
    """Size a :class:`GridSpec` from example frames (host side, numpy + scipy).

    The cell size is ``r`` unless every real node of every frame has its ``max_neighbors``-th
    neighbour within ``r / margin``: then k-nearest mode with ``cell_size = margin * max`` of
    those distances (smaller cells, fewer candidates). The grid spans the largest extent seen
    times ``margin``; the capacity is ``margin`` times the fullest run, rounded up to
    ``multiple``.

    Args:
        positions: ``[N, 3]`` or ``[F, N, 3]`` example frames.
        r: radius; max_neighbors: cap K; loop: as in ``radius_graph``.
        mask: ``[N]`` (or ``[F, N]``) bool, True for real nodes.
        cell_size: force this cell size (skips the k-nearest estimate).
        margin: safety factor (> 1) applied to sizes.
        multiple: round the capacity up to a multiple of this.

    Returns:
        The :class:`GridSpec`.
    """
    frames = np.asarray(positions, np.float32)
    frames = frames[None] if frames.ndim == 2 else frames
    masks = np.ones(frames.shape[:2], bool) if mask is None else np.asarray(mask, bool)
    masks = np.broadcast_to(masks, frames.shape[:2])
    pts = [f[m] for f, m in zip(frames, masks, strict=True)]
    if cell_size is None:
        kth = max(float(np.max(_kth_distance(p, r, max_neighbors, loop))) for p in pts)
        cell_size = r if margin * kth >= r else margin * kth
    extent = max(float(np.max(p.max(0) - p.min(0))) for p in pts)
    n_cells = max(1, math.ceil(margin * extent / cell_size) + 1)
    spec = GridSpec(float(cell_size), (n_cells,) * 3, 1)
    fullest = 1
    for f, m in zip(frames, masks, strict=True):
        c, cid = _cells(f, m, spec)
        first, last, ok = _runs(c, spec, np)
        s = np.sort(cid)
        lens = np.searchsorted(s, last, "right") - np.searchsorted(s, first, "left")
        fullest = max(fullest, int(np.max(np.where(ok & m[:, None], lens, 0))))
    cap = multiple * math.ceil(margin * fullest / multiple)
    return dataclasses.replace(spec, capacity=min(cap, multiple * math.ceil(len(f) / multiple)))


def grow(spec: GridSpec, r: float, factor: float = 2.0) -> GridSpec:
    """A larger spec after an overflow: more capacity, and in k-nearest mode larger cells."""
    cell = min(r, spec.cell_size * factor ** (1 / 3)) if spec.cell_size < r else spec.cell_size
    scale = cell / spec.cell_size
    shape = tuple(max(1, math.ceil(g / scale) + 1) for g in spec.grid_shape)
    cap = int(math.ceil(spec.capacity * factor * scale**3))
    return GridSpec(cell, shape, cap)
