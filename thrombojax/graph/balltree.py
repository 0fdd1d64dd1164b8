"""Erwin's ball tree (Zhdanov et al. 2025): a numpy reference and a jittable JAX build.

Facts taken from the official code (github.com/maxxxzdn/erwin, ``balltree/balltree.h`` and
``build_balltree_with_rotations`` in ``balltree.pyx``, ``models/erwin.py``):

* The tree is a perfect binary tree over ``P = 2**ceil(log2 n)`` *slots* (``n`` real points).
  A node holding ``c`` points (in slot order) is split on the axis of largest spread
  (``max - min``; ties: the first axis) at the median: the ``c // 2`` smallest go left,
  the rest right; each child owns half of the parent's slots. Splitting stops at leaves of
  2 slots; a leaf that received a single point holds it twice (the second copy is padding).
* Hence **a ball of size ``B`` at level ``l`` is a contiguous slice** ``[k*B, (k+1)*B)`` of the
  level's ordering, and coarsening by stride ``s`` (mean over ``s`` consecutive items) yields
  the next level's ordering: level ``l`` has ``P_l = P / prod(strides[:l])`` items.
* Rotated tree (cross-ball interaction): the *slots* of level 0 (``positions[perm]``, padding
  copies included) are rotated, ``x' = x @ R`` with :func:`rotation_matrix` (equal Euler angles,
  ``rotate`` degrees); at level ``l`` the rotated slots coarsened like the model does (mean over
  strides) are partitioned ``t_l = max(0, floor(log2(P / ball_sizes[l])))`` times (capped by
  ``log2 P_l``) by the same split rule with exact halves. ``rot_perm[l] [P_l]`` gives, for each
  rotated position, the index into the level-``l`` ordering: ``x_l[rot_perm[l]]`` is the
  rotated ordering (Erwin's ``tree_idx_rot``) and ``y[rot_inverse[l]]`` maps back.

Usage in an Erwin layer (``B`` ball size, ``s`` stride, features ``x [N, C]``)::

    tree = build_balltree(pos, mask=mask, strides=(2, 2, 2), ball_sizes=(128,) * 4, rotate=45)
    h, p = x[tree.perm], pos[tree.perm]           # level 0, [P, C]; balls: h.reshape(-1, B, C)
    hr = h[tree.rot_perm[0]]                       # rotated ordering of the same items
    h = block(hr, p[tree.rot_perm[0]])[tree.rot_inverse[0]]   # back to the tree ordering
    h1 = h.reshape(-1, s, C) ...; p1 = p.reshape(-1, s, 3).mean(1)   # level 1 (pooling)
    out = h[tree.inverse]                          # level 0 back to node order, [N, C]

Padding copies (``~slot_mask``) take part in balls like in Erwin; mask them (e.g. with
``level_mask``) where a statistic must see real nodes only.

Our differences (documented choices):

* Sorting is stable (``argsort``) instead of ``std::nth_element``: ties at a median go by the
  current order, so the numpy and JAX builds agree exactly; ball *membership* equals Erwin's
  whenever there are no ties. Coordinates are float32 (Erwin: float64).
* Static shapes: ``P = num_slots`` (default ``2**ceil(log2 N)`` of the padded row count ``N``)
  with ``n = mask.sum()`` real points. When ``n > P / 2`` this is Erwin's tree exactly. When
  ``n <= P / 2`` some leaves get no point: both their slots are padding copies of the next real
  point in slot order (or the last one). Padded rows (``mask`` False) never enter the tree.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from thrombojax.errors import ConfigError

__all__ = [
    "BallTree",
    "build_balltree",
    "build_balltree_numpy",
    "rotation_matrix",
    "default_num_slots",
    "level_sizes",
    "rotated_partitions",
]


@struct.dataclass
class BallTree:
    """A ball tree over ``P`` slots (pytree; arrays are jax or numpy).

    Attributes:
        perm: ``[P]`` int32, slot -> node index (Erwin's ``tree_idx``); ``x[perm]`` is level 0.
        slot_mask: ``[P]`` bool, True for the one slot of each real node (Erwin's ``tree_mask``);
            False for padding copies.
        inverse: ``[N]`` int32, node -> its slot, so ``y_slots[inverse]`` returns to node order
            (padded rows, ``mask`` False, point to slot 0: mask them).
        level_mask: per level ``l``, ``[P_l]`` bool: True where the coarse item covers at least
            one real node (all True when ``n > P / 2``).
        rot_perm: per level ``l``, ``[P_l]`` int32: rotated position -> index in level ``l``
            (Erwin's ``tree_idx_rot``); empty tuple when ``rotate == 0``.
        rot_inverse: per level ``l``, ``[P_l]`` int32, ``argsort(rot_perm[l])``.
        strides: static, the coarsening strides between levels.
        ball_sizes: static, the ball size of each level.
    """

    perm: jax.Array
    slot_mask: jax.Array
    inverse: jax.Array
    level_mask: tuple
    rot_perm: tuple
    rot_inverse: tuple
    strides: tuple = struct.field(pytree_node=False, default=())
    ball_sizes: tuple = struct.field(pytree_node=False, default=())

    @property
    def num_slots(self) -> int:
        return self.perm.shape[0]


def default_num_slots(n_rows: int) -> int:
    """``P = 2**ceil(log2 n_rows)`` (at least 2): Erwin's padded tree size."""
    return max(2, 1 << max(0, math.ceil(math.log2(max(n_rows, 1)))))


def level_sizes(num_slots: int, strides: tuple[int, ...]) -> tuple[int, ...]:
    """Number of items per level: ``P, P / s0, P / (s0 s1), ...`` (``len(strides) + 1`` levels)."""
    sizes = [num_slots]
    for s in strides:
        if s < 1 or sizes[-1] % s:
            raise ConfigError(f"ball tree: stride {s} does not divide level size {sizes[-1]}")
        sizes.append(sizes[-1] // s)
    return tuple(sizes)


def rotated_partitions(num_slots: int, strides, ball_sizes) -> tuple[int, ...]:
    """Erwin's number of rotated-tree splits per level, ``max(0, int(log2(P / ball_size)))``,
    capped so that a partition keeps at least one item."""
    sizes = level_sizes(num_slots, tuple(strides))
    return tuple(
        min(max(0, int(math.log2(num_slots / b))), int(math.log2(m)))
        for b, m in zip(ball_sizes, sizes, strict=True)
    )


def rotation_matrix(angle_deg: float) -> np.ndarray:
    """Erwin's 3-D rotation with the same Euler angle ``angle_deg`` about each axis.

    Applied to row vectors: ``x_rot = x @ R``. Returns ``[3, 3]`` float32.
    """
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    return np.array(
        [
            [c * c, s * c * (s - 1), s * (s + c * c)],
            [s * c, s * s * s + c * c, s * c * (s - 1)],
            [-s, s * c, c * c],
        ],
        np.float32,
    )


def _rotate(x, rot):
    """``x @ rot`` written out (same float32 rounding in numpy and XLA; ``rot`` numpy)."""
    cols = [x[:, 0] * rot[0, j] + x[:, 1] * rot[1, j] + x[:, 2] * rot[2, j] for j in range(3)]
    return (np if isinstance(x, np.ndarray) else jnp).stack(cols, axis=1)


def _check(positions_shape, num_slots, strides, ball_sizes, rotate):
    n_rows = positions_shape[0]
    p = default_num_slots(n_rows) if num_slots is None else int(num_slots)
    if p < n_rows or p & (p - 1) or p < 2:
        raise ConfigError(f"ball tree: num_slots={p} must be a power of two >= {n_rows} rows")
    if rotate and len(ball_sizes) != len(strides) + 1:
        raise ConfigError("ball tree: need len(ball_sizes) == len(strides) + 1 for rotated trees")
    level_sizes(p, tuple(strides))
    return p


# ---------------------------------------------------------------- numpy reference (recursive)


def _np_split_order(x: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Stable order of ``idx`` along the axis of largest spread of ``x[idx]``."""
    pts = x[idx]
    dim = int(np.argmax(pts.max(axis=0) - pts.min(axis=0)))
    return idx[np.argsort(pts[:, dim], kind="stable")]


def _np_tree(x, idx, n_slots):
    """Recursive build: returns the real-point order and per-leaf counts of a subtree."""
    if n_slots == 2:
        return list(idx), [len(idx)]
    if len(idx) > 1:
        idx = _np_split_order(x, idx)
    half = len(idx) // 2
    lo, lc = _np_tree(x, idx[:half], n_slots // 2)
    ro, rc = _np_tree(x, idx[half:], n_slots // 2)
    return lo + ro, lc + rc


def _np_partition(x, idx, levels):
    if levels == 0 or len(idx) <= 1:
        return list(idx)
    idx = _np_split_order(x, idx)
    h = len(idx) // 2
    return _np_partition(x, idx[:h], levels - 1) + _np_partition(x, idx[h:], levels - 1)


def _slots_from_leaves(order, leaf_counts, p):
    n = len(order)
    starts = np.concatenate([[0], np.cumsum(leaf_counts)[:-1]]).astype(np.int64)
    first = np.clip(starts, 0, max(n - 1, 0))
    second = np.clip(starts + (np.asarray(leaf_counts) == 2), 0, max(n - 1, 0))
    pos = np.stack([first, second], axis=1).reshape(p)
    smask = np.stack([np.asarray(leaf_counts) >= 1, np.asarray(leaf_counts) == 2], 1).reshape(p)
    order = np.asarray(order, np.int64) if n else np.zeros(1, np.int64)
    return order[pos], smask


def build_balltree_numpy(
    positions,
    *,
    mask=None,
    strides=(),
    ball_sizes=(),
    rotate: float = 0.0,
    num_slots: int | None = None,
) -> BallTree:
    """Reference ball tree (recursive numpy); arguments and result as :func:`build_balltree`."""
    x = np.asarray(positions, np.float32)
    p = _check(x.shape, num_slots, strides, ball_sizes, rotate)
    m = np.ones(len(x), bool) if mask is None else np.asarray(mask, bool)
    order, counts = _np_tree(x, np.flatnonzero(m), p)
    perm, smask = _slots_from_leaves(order, counts, p)
    inverse = np.zeros(len(x), np.int64)
    inverse[perm[smask]] = np.flatnonzero(smask)
    level_mask, rp, ri = [smask], [], []
    for s in strides:
        level_mask.append(level_mask[-1].reshape(-1, s).any(axis=1))
    if rotate:
        pts = _rotate(x[perm], rotation_matrix(rotate))
        for lvl, t in enumerate(rotated_partitions(p, strides, ball_sizes)):
            rperm = np.asarray(_np_partition(pts, np.arange(len(pts)), t), np.int32)
            rp.append(rperm)
            ri.append(np.argsort(rperm).astype(np.int32))
            if lvl < len(strides):
                pts = pts.reshape(-1, strides[lvl], 3).mean(axis=1, dtype=np.float32)
    return BallTree(
        perm=perm.astype(np.int32),
        slot_mask=smask,
        inverse=inverse.astype(np.int32),
        level_mask=tuple(level_mask),
        rot_perm=tuple(rp),
        rot_inverse=tuple(ri),
        strides=tuple(strides),
        ball_sizes=tuple(ball_sizes),
    )


# ---------------------------------------------------------------- jittable JAX build


def _split_levels(x, order, leaf_seg, n_leaves, levels, first=0):
    """Levels ``first..levels-1`` of splits in one ``fori_loop`` (one compiled body): at level
    ``l`` the segment of a position is ``leaf_seg >> (L - l)`` (segments are nested); stable
    sort of ``order`` by (segment, coordinate on the segment's axis of largest spread)."""
    depth = int(math.log2(n_leaves))

    def body(lvl, order):
        seg = jnp.right_shift(leaf_seg, depth - lvl)
        pts = x[order]
        kw = dict(num_segments=n_leaves + 1, indices_are_sorted=True)
        spread = jax.ops.segment_max(pts, seg, **kw) - jax.ops.segment_min(pts, seg, **kw)
        dim = jnp.argmax(spread, axis=1)
        val = jnp.take_along_axis(pts, dim[seg][:, None], axis=1)[:, 0]
        return jax.lax.sort((seg, val, order), num_keys=2, is_stable=True)[2]

    return jax.lax.fori_loop(first, levels, body, order)


def _leaf_bounds(n, n_leaves):
    """Boundaries ``[n_leaves + 1]`` of the leaves after recursive floor halving of ``n``."""
    bounds = jnp.stack([jnp.int32(0), n])
    while bounds.shape[0] < n_leaves + 1:
        mids = (bounds[:-1] + bounds[1:]) // 2
        inter = jnp.stack([bounds[:-1], mids], axis=1).reshape(-1)
        bounds = jnp.concatenate([inter, bounds[-1:]])
    return bounds


def _iota(n):
    return jnp.arange(n, dtype=jnp.int32)


def _jax_partition(pts, levels):
    """Erwin's ``partition_ball_tree`` on ``[M, 3]`` (M a power of two), exact halves."""
    m = pts.shape[0]
    n_leaves = 1 << levels
    return _split_levels(pts, _iota(m), _iota(m) // (m // n_leaves), n_leaves, levels)


def build_balltree(
    positions: jax.Array,
    *,
    mask: jax.Array | None = None,
    strides: tuple[int, ...] = (),
    ball_sizes: tuple[int, ...] = (),
    rotate: float = 0.0,
    num_slots: int | None = None,
) -> BallTree:
    """Erwin's ball tree of ``positions`` (and its rotated trees), jittable, static shapes.

    One stable sort per tree level on the whole padded cloud (``log2 P - 1`` sorts, in a
    ``fori_loop``) keyed by (segment, coordinate on the segment's widest axis). See the module
    docstring for the slot layout, the padding rule and the rotated trees.

    Args:
        positions: ``[N, 3]`` float positions (scaled coordinates).
        mask: ``[N]`` bool, True for real rows; padded rows never enter the tree.
        strides: static coarsening strides between levels (Erwin's ``strides``), e.g. ``(2, 2, 2)``.
        ball_sizes: static ball size per level (``len(strides) + 1`` values) - used for the
            rotated trees' depth.
        rotate: static angle in degrees of the rotated trees (0: none).
        num_slots: static ``P`` (power of two ``>= N``); default ``2**ceil(log2 N)``.

    Returns:
        A :class:`BallTree` (``perm [P]``, ``slot_mask [P]``, ``inverse [N]``, ``level_mask``,
        ``rot_perm``, ``rot_inverse``).
    """
    x = jnp.asarray(positions, jnp.float32)
    n_rows = x.shape[0]
    p = _check(x.shape, num_slots, strides, ball_sizes, rotate)
    m = jnp.ones(n_rows, bool) if mask is None else jnp.asarray(mask, bool)
    n = jnp.sum(m, dtype=jnp.int32)
    order = jnp.argsort(~m, stable=True).astype(jnp.int32)  # real rows first, by index
    n_leaves = p // 2
    bounds = _leaf_bounds(n, n_leaves)
    marks = jnp.zeros(n_rows + 1, jnp.int32).at[bounds[1:]].add(1)
    leaf_seg = jnp.cumsum(marks)[:n_rows]  # leaf of each position (padding: n_leaves)
    order = _split_levels(x, order, leaf_seg, n_leaves, int(math.log2(n_leaves)))
    counts = bounds[1:] - bounds[:-1]
    starts = bounds[:-1]
    top = jnp.maximum(n - 1, 0)
    pos = jnp.stack([jnp.clip(starts, 0, top), jnp.clip(starts + (counts == 2), 0, top)], 1)
    perm = order[pos.reshape(p)]
    smask = jnp.stack([counts >= 1, counts == 2], axis=1).reshape(p)
    slots = jnp.where(smask, perm, n_rows)
    inverse = jnp.zeros(n_rows, jnp.int32).at[slots].set(_iota(p), mode="drop")
    level_mask = [smask]
    for s in strides:
        level_mask.append(level_mask[-1].reshape(-1, s).any(axis=1))
    rp, ri = [], []
    if rotate:
        pts = _rotate(x[perm], rotation_matrix(rotate))
        for lvl, t in enumerate(rotated_partitions(p, strides, ball_sizes)):
            rperm = _jax_partition(pts, t)
            rp.append(rperm)
            ri.append(jnp.argsort(rperm).astype(jnp.int32))
            if lvl < len(strides):
                pts = pts.reshape(-1, strides[lvl], 3).mean(axis=1)
    return BallTree(
        perm=perm.astype(jnp.int32),
        slot_mask=smask,
        inverse=inverse,
        level_mask=tuple(level_mask),
        rot_perm=tuple(rp),
        rot_inverse=tuple(ri),
        strides=tuple(strides),
        ball_sizes=tuple(ball_sizes),
    )
