"""The dense radius graph's block-pruned selection: Morton order, the exact fallback for rows
whose K nearest may lie outside the kept blocks, and vmap over a batch."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_neighbors import K, assert_matches, cube, vessel_frame

from thrombojax.graph import NeighborList
from thrombojax.graph.dense import dense_search, morton_order


def search(x, r, k=K, mask=None, loop=False, **kw):
    """``dense_search`` under jit -> (NeighborList, n_redo)."""
    mask = np.ones(len(x), bool) if mask is None else mask
    fn = jax.jit(lambda p, m: dense_search(p, r, k, m, loop, **kw))
    ids, counts, n_redo = fn(x, mask)
    return NeighborList(ids, counts, jnp.zeros((), bool)), int(n_redo)


def test_morton_order_is_local_with_padding_last():
    x = vessel_frame(1000, seed=3)
    mask = np.arange(1000) % 7 != 0
    perm = np.asarray(morton_order(jnp.asarray(x), jnp.asarray(mask)))
    assert sorted(perm) == list(range(1000))
    assert not mask[perm[mask.sum() :]].any() and mask[perm[: mask.sum()]].all()
    real = x[perm[: mask.sum()]]
    step = np.linalg.norm(np.diff(real, axis=0), axis=1)
    random_pair = np.linalg.norm(real - real[::-1], axis=1)
    assert np.median(step) < 0.1 * np.median(random_pair), "Morton neighbours are not close"


def test_vessel_frame_at_the_study_radius_needs_no_fallback():
    x = vessel_frame(2048, seed=4)
    nbrs, n_redo = search(x, 0.56)
    assert n_redo == 0  # the pruned selection alone is exact here (the fast path)
    assert_matches(nbrs, x, 0.56, K)


@pytest.mark.parametrize(("max_blocks", "loop"), [(2, False), (3, True)])
def test_fallback_rows_are_recomputed_exactly(max_blocks, loop):
    x = vessel_frame(700, seed=5)
    mask = np.random.default_rng(5).uniform(size=700) > 0.1
    nbrs, n_redo = search(x, 0.56, mask=mask, loop=loop, max_blocks=max_blocks, chunk=7)
    assert n_redo > 7  # several fallback iterations ran
    assert_matches(nbrs, x, 0.56, K, mask=mask, loop=loop)


def test_sparse_rows_with_fewer_than_k_neighbours():
    x = cube(2048, seed=6)  # about 29 neighbours within 0.3: the K-th distance is inf
    nbrs, _ = search(x, 0.3)
    assert_matches(nbrs, x, 0.3, K)
    nbrs, n_redo = search(x, 0.3, max_blocks=2, chunk=64)
    assert n_redo > 64
    assert_matches(nbrs, x, 0.3, K)


def test_two_stage_fallback(monkeypatch):
    """Fallback rows select over all columns with ``smallest_k``'s two-stage path too."""
    from thrombojax.graph import grid

    monkeypatch.setattr(grid, "_TWO_STAGE_MIN", 64)
    x = vessel_frame(2048, seed=8)
    mask = np.arange(len(x)) < 2000
    nbrs, n_redo = search(x, 0.56, mask=mask, max_blocks=2)
    assert n_redo > 0
    assert_matches(nbrs, x, 0.56, K, mask=mask)


def test_vmap_over_a_batch_with_different_fallbacks():
    xb = np.stack([vessel_frame(600, seed=s) for s in (9, 10)])
    mb = np.stack([np.arange(600) < 550, np.arange(600) < 600])
    fn = jax.vmap(lambda p, m: dense_search(p, 0.56, K, m, False, max_blocks=2, chunk=16))
    ids, counts, n_redo = jax.jit(fn)(xb, mb)
    assert n_redo[0] != n_redo[1]
    for b in range(2):
        one, _ = search(xb[b], 0.56, mask=mb[b], max_blocks=2, chunk=16)
        np.testing.assert_array_equal(np.asarray(ids[b]), np.asarray(one.indices))
        np.testing.assert_array_equal(np.asarray(counts[b]), np.asarray(one.counts))
