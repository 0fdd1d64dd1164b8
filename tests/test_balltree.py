"""Erwin ball tree: JAX build == numpy reference, same balls as an independent nth_element-style
recursion (Erwin's algorithm), padding, inverse permutation, compactness, rotated trees."""

from collections import Counter

import jax
import numpy as np
import pytest

from thrombojax.errors import ConfigError
from thrombojax.graph import (
    build_balltree,
    build_balltree_numpy,
    default_num_slots,
    level_sizes,
    rotated_partitions,
    rotation_matrix,
)

TREE = {"strides": (2, 2, 2), "ball_sizes": (16, 16, 16, 16), "rotate": 45.0}


def cloud(n, seed=0):
    return np.random.default_rng(seed).normal(size=(n, 3)).astype(np.float32)


def erwin_balls(x, idx, n_slots, out):
    """Erwin's build_tree: widest axis, nth_element-style median split (left gets c // 2),
    stop at leaves of 2 slots. Appends (level, frozenset) for every subtree."""
    out.append((n_slots, frozenset(idx.tolist())))
    if n_slots == 2:
        return
    half = len(idx) // 2
    if len(idx) > 1:
        pts = x[idx]
        dim = int(np.argmax(pts.max(0) - pts.min(0)))
        idx = idx[np.argpartition(pts[:, dim], half)] if half < len(idx) else idx
    erwin_balls(x, idx[:half], n_slots // 2, out)
    erwin_balls(x, idx[half:], n_slots // 2, out)


def tree_balls(tree):
    """(slots per subtree, real members) of every subtree, from the slot layout."""
    perm, smask = np.asarray(tree.perm), np.asarray(tree.slot_mask)
    p, out, size = len(perm), [], len(perm)
    while size >= 2:
        for start in range(0, p, size):
            sl = slice(start, start + size)
            out.append((size, frozenset(perm[sl][smask[sl]].tolist())))
        size //= 2
    return out


@pytest.mark.parametrize(("n_rows", "n_real"), [(1024, 1024), (977, 977), (700, 300), (5, 5)])
def test_jax_tree_equals_numpy_and_erwin(n_rows, n_real):
    x = cloud(n_rows, seed=n_rows)
    mask = np.zeros(n_rows, bool)
    mask[np.random.default_rng(1).permutation(n_rows)[:n_real]] = True
    kw = TREE if n_rows >= 512 else {}
    ref = build_balltree_numpy(x, mask=mask, **kw)
    got = jax.jit(lambda p, m: build_balltree(p, mask=m, **kw))(x, mask)
    p = default_num_slots(n_rows)
    assert got.perm.shape == (p,) and got.inverse.shape == (n_rows,)
    for name in ("perm", "slot_mask", "inverse"):
        np.testing.assert_array_equal(np.asarray(getattr(got, name)), getattr(ref, name), name)
    for a, b in zip(got.level_mask, ref.level_mask, strict=True):
        np.testing.assert_array_equal(np.asarray(a), b)
    for a, b in zip(got.rot_perm + got.rot_inverse, ref.rot_perm + ref.rot_inverse, strict=True):
        np.testing.assert_array_equal(np.asarray(a), b)
    # same balls at every level as Erwin's recursion (membership; order inside may differ)
    if p == default_num_slots(n_real):
        want = []
        erwin_balls(x, np.flatnonzero(mask), p, want)
        assert Counter(tree_balls(got)) == Counter(want)


def test_slot_layout_padding_and_inverse():
    x = cloud(977, seed=3)
    tree = jax.jit(lambda p: build_balltree(p, strides=(2, 2)))(x)
    perm, smask, inv = (np.asarray(a) for a in (tree.perm, tree.slot_mask, tree.inverse))
    assert tree.num_slots == 1024 and smask.sum() == 977
    np.testing.assert_array_equal(np.sort(perm[smask]), np.arange(977))  # each node once
    np.testing.assert_array_equal(perm[inv], np.arange(977))  # inverse round trip
    pad = np.flatnonzero(~smask)
    assert np.all(pad % 2 == 1) and np.all(perm[pad] == perm[pad - 1])  # copy within its leaf
    assert all(np.asarray(m).all() for m in tree.level_mask[1:])  # n > P/2: no empty leaf


def test_padded_rows_never_enter_the_tree():
    x = cloud(600, seed=4)
    mask = np.arange(600) < 400
    x[~mask] = 1e6  # padding far away must not matter
    tree = jax.jit(lambda p, m: build_balltree(p, mask=m, num_slots=1024))(x, mask)
    perm, smask = np.asarray(tree.perm), np.asarray(tree.slot_mask)
    assert np.all(perm < 400) and smask.sum() == 400
    assert not np.asarray(tree.level_mask[0]).all()  # n <= P/2: some empty leaves
    np.testing.assert_array_equal(perm[np.asarray(tree.inverse)[:400]], np.arange(400))


def test_balls_are_spatially_compact():
    x = np.random.default_rng(5).uniform(-1, 1, (2048, 3)).astype(np.float32)
    tree = jax.jit(lambda p: build_balltree(p, **TREE))(x)
    pts = x[np.asarray(tree.perm)]
    rng = np.random.default_rng(0)

    def mean_ball_radius(p, size):
        b = p.reshape(-1, size, 3)
        return np.linalg.norm(b - b.mean(1, keepdims=True), axis=-1).mean()

    for size, ratio in ((16, 0.35), (128, 0.6)):  # volume fractions 1/128, 1/16 of the cube
        tight = mean_ball_radius(pts, size)
        loose = mean_ball_radius(pts[rng.permutation(len(pts))], size)
        assert tight < ratio * loose, (size, tight, loose)
    # rotated balls are compact too, and they are different balls (cross-ball mixing)
    rot = pts[np.asarray(tree.rot_perm[0])]
    assert mean_ball_radius(rot, 16) < 0.35 * mean_ball_radius(pts[rng.permutation(2048)], 16)
    same = [
        set(np.asarray(tree.perm)[i : i + 16])
        == set(np.asarray(tree.perm)[np.asarray(tree.rot_perm[0])][i : i + 16])
        for i in range(0, 2048, 16)
    ]
    assert np.mean(same) < 0.5


def test_rotated_tree_levels_follow_erwin():
    p = 2048
    assert level_sizes(p, (2, 2, 2)) == (2048, 1024, 512, 256)
    assert rotated_partitions(p, (2, 2, 2), (128, 128, 128, 128)) == (4, 4, 4, 4)
    assert rotated_partitions(64, (2, 2), (16, 16, 16)) == (2, 2, 2)
    r = rotation_matrix(45.0)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-6)
    assert abs(np.linalg.det(r) - 1) < 1e-6
    tree = jax.jit(lambda x: build_balltree(x, **TREE))(cloud(p, seed=6))
    for lvl, (rp, ri) in enumerate(zip(tree.rot_perm, tree.rot_inverse, strict=True)):
        size = level_sizes(p, TREE["strides"])[lvl]
        rp, ri = np.asarray(rp), np.asarray(ri)
        np.testing.assert_array_equal(np.sort(rp), np.arange(size))
        np.testing.assert_array_equal(rp[ri], np.arange(size))


def test_bad_configuration_raises():
    with pytest.raises(ConfigError):
        build_balltree_numpy(cloud(100), num_slots=100)
    with pytest.raises(ConfigError):
        build_balltree_numpy(cloud(100), strides=(3,), ball_sizes=(8, 8), rotate=45.0)
    with pytest.raises(ConfigError):
        build_balltree_numpy(cloud(100), strides=(2,), ball_sizes=(8,), rotate=45.0)


def test_vmap_and_empty_mask():
    xb = np.stack([cloud(100, seed=s) for s in (8, 9)])
    mb = np.stack([np.arange(100) < 70, np.zeros(100, bool)])
    fn = jax.jit(jax.vmap(lambda p, m: build_balltree(p, mask=m)))
    trees = fn(xb, mb)
    ref = build_balltree_numpy(xb[0], mask=mb[0])
    np.testing.assert_array_equal(np.asarray(trees.perm[0]), ref.perm)
    assert not np.asarray(trees.slot_mask[1]).any()  # no real node: every slot is padding
