"""Host-side sizing of the cell grid (the *allocate* half of jax-md's allocate / update).

:func:`estimate_capacity` sizes a :class:`~thrombojax.graph.grid.GridSpec` from example frames
(numpy + scipy, outside ``jit``); :func:`grow` enlarges one after an overflow. The jittable
search that uses the spec is :func:`thrombojax.graph.grid.grid_search`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.spatial import cKDTree

from thrombojax.graph.grid import _MAX_CELLS_PER_AXIS, GridSpec, _query_runs

__all__ = ["estimate_capacity", "grow"]


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
    times ``margin``. Capacities are ``margin`` times the run sizes seen, rounded up to
    ``multiple``; the light / heavy split minimises the number of candidates examined. In
    k-nearest mode the heavy nodes (the dense clot) then get a finer grid when it reads fewer
    slots: cell ``margin`` times their largest K-th neighbour distance (on the solver's 27k
    clotentry frames this cut the grid search from ~0.45 s to ~0.27 s).

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
    n_cells = min(_MAX_CELLS_PER_AXIS, max(1, math.ceil(margin * extent / cell_size) + 1))
    spec = GridSpec(float(cell_size), (n_cells,) * 3, 1)
    weights = []
    for f, m in zip(frames, masks, strict=True):
        _, start, end, live = _query_runs(f, m, spec, np)
        weights.append(np.sort(np.max(np.where(live, end - start, 0), axis=1)))
    n = frames.shape[1]

    def rounded(v):
        return max(multiple, multiple * math.ceil(margin * v / multiple))

    best = None
    for frac in (0.0, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6):
        n_heavy = min(n, math.ceil(margin * frac * n))
        light = rounded(max(int(w[max(0, n - n_heavy - 1)]) for w in weights))
        heavy = rounded(max(int(w[-1]) for w in weights))
        candidates = [
            dataclasses.replace(
                spec, capacity=light, heavy_capacity=heavy if n_heavy else 0, heavy_nodes=n_heavy
            )
        ]
        if n_heavy and cell_size < r:  # k-nearest mode: the heavy nodes may use a finer grid
            candidates.append(
                _finer_heavy_grid(
                    candidates[0], frames, masks, r, max_neighbors, loop, margin, rounded
                )
            )
        for c in candidates:
            cost = (n - n_heavy) * c.capacity + n_heavy * c.heavy_capacity
            if best is None or cost < best[0]:
                best = (cost, c)
    return best[1]


def _heavy_nodes(frame, mask, spec):
    """Node ids of the heavy nodes of one frame, chosen exactly as :func:`grid_search` does."""
    n = len(frame)
    order, start, end, live = _query_runs(frame, mask, spec, np)
    end = np.where(mask[order][:, None], end, -1)
    weight = np.max(np.where(live, end - start, 0), axis=1)
    heavy = order[np.argsort(weight, kind="stable")[n - min(spec.heavy_nodes, n) :]]
    return heavy[mask[heavy]]


def _finer_heavy_grid(spec, frames, masks, r, k, loop, margin, rounded):
    """k-nearest mode: give the heavy nodes (dense regions) a finer grid when it is cheaper.

    Its cell is ``margin`` times the largest K-th neighbour distance of the heavy nodes of any
    frame, its capacity ``margin`` times their largest run in it."""
    heavy = [_heavy_nodes(f, m, spec) for f, m in zip(frames, masks, strict=True)]
    kk = k + (0 if loop else 1)
    kth = 0.0
    for f, m, h in zip(frames, masks, heavy, strict=True):
        pts = f[m]
        if len(h) == 0 or len(pts) < kk:
            return spec
        d, _ = cKDTree(pts).query(f[h], k=kk, distance_upper_bound=r)
        kth = max(kth, float(np.max(d.reshape(len(h), kk)[:, -1])))
    cell = margin * kth
    if not np.isfinite(cell) or cell >= 0.8 * spec.cell_size:
        return spec
    extent = max(
        float(np.max(f[m].max(0) - f[m].min(0))) for f, m in zip(frames, masks, strict=True)
    )
    n_cells = min(_MAX_CELLS_PER_AXIS, max(1, math.ceil(margin * extent / cell) + 1))
    fine = GridSpec(cell, (n_cells,) * 3, 1)
    cap = 0
    for f, m, h in zip(frames, masks, heavy, strict=True):
        order, start, end, live = _query_runs(f, m, fine, np)
        rank = np.empty(len(f), np.int64)
        rank[order] = np.arange(len(f))
        runs = np.where(live, end - start, 0)[rank[h]]
        cap = max(cap, int(np.max(runs)))
    cap = rounded(cap)
    if cap >= spec.heavy_capacity:
        return spec
    return dataclasses.replace(
        spec, heavy_capacity=cap, heavy_cell_size=float(cell), heavy_grid_shape=(n_cells,) * 3
    )


def grow(spec: GridSpec, r: float, factor: float = 2.0) -> GridSpec:
    """A larger spec after an overflow: more capacity and heavy nodes, and in k-nearest mode
    larger cells. With a finer heavy grid the first grid keeps its cells (so the same nodes
    stay heavy) and the finer one grows, until it is as coarse as the first."""
    if spec.heavy_cell_size > 0:
        fine = grow(spec.heavy_spec(), r, factor)
        if fine.cell_size < spec.cell_size:
            cap = int(math.ceil(spec.capacity * factor))
            return dataclasses.replace(
                spec,
                capacity=cap,
                heavy_capacity=fine.capacity,
                heavy_cell_size=fine.cell_size,
                heavy_grid_shape=fine.grid_shape,
            )
        spec = dataclasses.replace(spec, heavy_cell_size=0.0, heavy_grid_shape=(1, 1, 1))
    cell = min(r, spec.cell_size * factor ** (1 / 3)) if spec.cell_size < r else spec.cell_size
    scale = cell / spec.cell_size
    shape = tuple(max(1, math.ceil(g / scale) + 1) for g in spec.grid_shape)
    cap = int(math.ceil(spec.capacity * factor * scale**3))
    heavy = int(math.ceil(max(spec.heavy_capacity, spec.capacity) * factor * scale**3))
    return GridSpec(cell, shape, cap, heavy, max(1, int(math.ceil(spec.heavy_nodes * factor))))
