"""Dense radius graph: tiled all-pairs distances with an exact, block-pruned K-nearest selection.

Used by :func:`thrombojax.graph.radius_graph` (``method="dense"``); see its module docstring for
the conventions (K nearest within ``r``, nearest first, sentinel ``N``, counts before the cap).

Why not simply ``lax.top_k`` over every row: on the CPU ``lax.top_k`` is a single-threaded
partial sort that costs ~4 ns per candidate, ~80 % of a 2,048-node search with all 2,048
columns as candidates. The distances themselves are cheap: computed per coordinate on
``[tile, N]`` arrays they vectorise (a ``[tile, N, 3]`` difference reduced over its last axis
does not: ~5x slower), and tiles small enough to stay in cache. So the candidates are pruned
first, exactly:

1. Nodes are put in Morton (z-curve) order, so consecutive nodes are close in space, and the
   columns are cut into ``nb`` *blocks* of ``block`` consecutive nodes.
2. For each row, the minimum distance in each block (one cheap reduction) ranks the blocks;
   ``lax.top_k`` over the ``nb`` block minima keeps the ``C = max_blocks`` nearest blocks.
3. ``lax.top_k`` over the ``C * block`` distances of those blocks gives the K nearest among them,
   with ``v_K`` the K-th distance (``inf`` if fewer than K lie within ``r``).
4. The selection is exact unless some block that was not kept holds a distance ``< v_K``, which
   happens iff more than ``C`` blocks have a minimum ``< v_K`` (the kept blocks are the ``C``
   smallest minima). Such rows are recomputed over all columns in a ``lax.while_loop`` over
   chunks of ``chunk`` rows, so the result is always exact; on vessel frames at the study's
   radii no row needs it (``block=16``, ``C = 16``: 256 candidates instead of 2,048).

Measured on the 2-core CPU here: 9-11 ms at N = 2,048 (``lax.top_k`` over all columns:
16-23 ms). ``counts`` (neighbours within ``r`` before the cap) are counted over all columns.
Exact distance ties are broken by the position in Morton order (deterministic, not by node
index). Peak memory is one ``[tile_rows, N]`` tile (never ``N x N``).

XLA note: ``lax.top_k`` only becomes the CPU ``TopK`` kernel when its outputs are used whole;
slicing them (e.g. ``values[:, k - 1]``) turns it into a full sort (~5x slower), hence the
``max`` below instead of a slice.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.graph.grid import smallest_k

__all__ = ["BLOCK", "dense_search", "morton_order"]

BLOCK: int = 16
"""Nodes per candidate block (Morton-consecutive)."""
_MIN_BLOCKS = 16  # blocks kept per row: max(_MIN_BLOCKS, ceil(8 K / BLOCK))
_TILE_ELEMENTS = 1 << 19  # tile_rows * N <= this (small tiles stay in cache)
_MIN_TILE_ROWS = 16
_CHUNK = 32  # rows per iteration of the exact fallback


def _spread_bits(v: jax.Array) -> jax.Array:
    """10-bit unsigned ints -> the same bits at every third position (uint32)."""
    v = v & jnp.uint32(0x3FF)
    v = (v | (v << 16)) & jnp.uint32(0x030000FF)
    v = (v | (v << 8)) & jnp.uint32(0x0300F00F)
    v = (v | (v << 4)) & jnp.uint32(0x030C30C3)
    return (v | (v << 2)) & jnp.uint32(0x09249249)


def morton_order(positions: jax.Array, mask: jax.Array) -> jax.Array:
    """``[N]`` int32 permutation sorting real nodes along a 30-bit Morton curve, padding last.

    The curve spans the bounding cube of the real nodes (1,024 cells per axis); ties keep the
    input order (stable sort).
    """
    big = jnp.asarray(jnp.finfo(positions.dtype).max, positions.dtype)
    lo = jnp.min(jnp.where(mask[:, None], positions, big), axis=0)
    hi = jnp.max(jnp.where(mask[:, None], positions, -big), axis=0)
    extent = jnp.maximum(jnp.max(hi - lo), jnp.finfo(positions.dtype).tiny)
    q = jnp.clip((positions - lo) / extent * 1023.0, 0.0, 1023.0).astype(jnp.uint32)
    code = _spread_bits(q[:, 0]) | (_spread_bits(q[:, 1]) << 1) | (_spread_bits(q[:, 2]) << 2)
    code = jnp.where(mask, code, jnp.uint32(0xFFFFFFFF))
    return jnp.argsort(code, stable=True).astype(jnp.int32)


def dense_search(
    positions: jax.Array,
    r: float,
    k: int,
    mask: jax.Array,
    loop: bool,
    tile_rows: int | None = None,
    *,
    block: int = BLOCK,
    max_blocks: int | None = None,
    chunk: int = _CHUNK,
) -> tuple[jax.Array, jax.Array]:
    """The K nearest neighbours within ``r`` of every node by tiled all-pairs distances.

    Args:
        positions: ``[N, 3]`` float.
        r: radius (strict ``<``); k: capacity K.
        mask: ``[N]`` bool, True for real nodes; loop: include ``i`` in its own list.
        tile_rows: rows per tile (default ``tile_rows * N <= 2**19``, at least 16).
        block: nodes per candidate block; max_blocks: blocks kept per row (default
            ``max(16, ceil(8 K / block))``); rows whose answer may lie outside them are
            recomputed over all columns. chunk: rows per fallback iteration.

    Returns:
        ``indices [N, K]`` int32 (nearest first, sentinel ``N``), ``counts [N]`` int32 and
        ``n_redo []`` int32, the number of rows recomputed over all columns (a diagnostic).
    """
    n = positions.shape[0]
    nb = -(-n // block)
    m = nb * block
    c = max_blocks or max(_MIN_BLOCKS, -(-8 * k // block))
    pruned = c < nb and c * block >= k
    perm = morton_order(positions, mask)
    order = jnp.concatenate([perm, jnp.full((m - n,), n, jnp.int32)])  # padding columns -> n
    xs = jnp.concatenate([positions, jnp.zeros((1, 3), positions.dtype)])[order]  # [m, 3]
    ms = jnp.concatenate([mask, jnp.zeros((1,), bool)])[order]
    cols, col_id = xs.T, jnp.arange(m, dtype=jnp.int32)
    r2 = jnp.asarray(r, positions.dtype) ** 2

    def distances(rows):
        """``[T, m]`` squared distances of sorted rows ``rows`` (inf if not a neighbour)."""
        xq = xs[rows]
        d2 = sum((xq[:, a : a + 1] - cols[a][None, :]) ** 2 for a in range(3))
        ok = ms[None, :] & ms[rows][:, None] & (d2 < r2)
        if not loop:
            ok = ok & (rows[:, None] != col_id[None, :])
        return jnp.where(ok, d2, jnp.inf), jnp.sum(ok, axis=-1, dtype=jnp.int32)

    def select_all(d2):
        vals, pos = smallest_k(d2, min(k, m))
        ids = jnp.where(jnp.isfinite(vals), pos, m)
        return jnp.pad(ids, ((0, 0), (0, k - ids.shape[1])), constant_values=m)

    def select_pruned(d2):
        t = d2.shape[0]
        blocks = d2.reshape(t, nb, block)
        bmin = jnp.min(blocks, axis=-1)
        _, kept = jax.lax.top_k(-bmin, c)  # [t, c] nearest blocks
        vals = jnp.take_along_axis(blocks, kept[:, :, None], axis=1).reshape(t, c * block)
        neg, pos = jax.lax.top_k(-vals, k)
        ids = kept.reshape(-1)[jnp.arange(t)[:, None] * c + pos // block] * block + pos % block
        ids = jnp.where(jnp.isfinite(neg), ids, m)
        v_k = jnp.max(-neg, axis=-1, keepdims=True)  # not neg[:, -1]: see the module note
        return ids.astype(jnp.int32), jnp.sum(bmin < v_k, axis=-1) > c

    t = tile_rows or min(m, max(_MIN_TILE_ROWS, _TILE_ELEMENTS // m))
    n_tiles = -(-m // t)
    rows = jnp.minimum(jnp.arange(n_tiles * t, dtype=jnp.int32), m - 1).reshape(n_tiles, t)

    def tile(rows):
        d2, counts = distances(rows)
        if not pruned:
            return select_all(d2), counts, jnp.zeros(rows.shape, bool)
        ids, redo = select_pruned(d2)
        return ids, counts, redo

    ids, counts, redo = jax.lax.map(tile, rows)
    ids, counts, redo = ids.reshape(-1, k)[:m], counts.reshape(-1)[:m], redo.reshape(-1)[:m]
    n_redo = jnp.sum(redo, dtype=jnp.int32)
    if pruned:
        ids = _redo_rows(ids, redo, n_redo, distances, select_all, chunk, m)
    # back from Morton order to the input order; sorted sentinel m -> N
    to_input = jnp.concatenate([order, jnp.array([n], jnp.int32)])[ids]
    inverse = jnp.zeros((n,), jnp.int32).at[perm].set(jnp.arange(n, dtype=jnp.int32))
    return to_input[inverse], counts[inverse], n_redo


def _redo_rows(ids, redo, n_redo, distances, select_all, chunk, m):
    """Recompute the ``n_redo`` rows flagged ``redo`` over all columns, ``chunk`` per iteration."""
    todo = jnp.argsort(~redo, stable=True).astype(jnp.int32)  # flagged rows first
    todo = jnp.concatenate([todo, jnp.zeros((chunk,), jnp.int32)])

    def body(state):
        i, ids = state
        rows = jax.lax.dynamic_slice(todo, (i * chunk,), (chunk,))
        live = i * chunk + jnp.arange(chunk) < n_redo
        new = select_all(distances(rows)[0]).astype(ids.dtype)
        return i + 1, ids.at[jnp.where(live, rows, m)].set(new, mode="drop")

    _, ids = jax.lax.while_loop(lambda s: s[0] * chunk < n_redo, body, (jnp.int32(0), ids))
    return ids
