"""The pruned wall searches give exactly what ``lax.top_k`` and ``jnp.argmin`` give."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from thrombojax.graph.wall_nodes import (
    SEARCH_BLOCK,
    WALL_NORMAL_NODES,
    first_min,
    nearest_vessel_node,
    smallest_first,
    wall_patches,
)
from thrombojax.types import NodeType


def _reference(key, k):
    return np.asarray(jax.lax.top_k(-jnp.asarray(key), k)[1])


@pytest.mark.parametrize("m", [300, 1600, 2048, 2050])
@pytest.mark.parametrize("k", [1, 3, WALL_NORMAL_NODES])
@pytest.mark.parametrize("values", [5, 400])
def test_smallest_first_is_top_k_with_its_ties(m, k, values):
    """Keys from 5 values (ties everywhere, also between block minima) or 400 (blocks with
    different minima holding equal keys), masked columns (inf),
    rows with fewer than k finite keys, the k smallest packed in one block, a padded last
    block: the same columns in the same order as lax.top_k, on both paths (m = 300 is
    below the pruning's threshold)."""
    rng = np.random.default_rng(m + k + values)
    key = rng.integers(0, values, size=(64, m)).astype(np.float32)
    key[:, rng.random(m) < 0.3] = np.inf  # columns that are not vessel nodes
    key[0, :] = np.inf
    key[1, :] = np.inf
    key[1, [m - 1, 7]] = 0.0  # fewer than k finite, one in the last (padded) block
    key[2, :] = 10.0
    key[2, 5 * SEARCH_BLOCK: 5 * SEARCH_BLOCK + k] = -1.0  # all k in one block
    key[3] = rng.permutation(m).astype(np.float32)  # no ties
    got = np.asarray(jax.jit(lambda a: smallest_first(a, k))(key))
    assert got.dtype == np.int32 and got.shape == (64, k)
    np.testing.assert_array_equal(got, _reference(key, k))


def test_first_min_is_argmin_also_with_nan_and_inf():
    d = np.array([[3.0, np.nan, 1.0, np.nan, 1.0], [np.nan] * 5, [np.inf] * 5,
                  [2.0, 1.0, 1.0, 0.5, 0.5], [-np.inf, 0.0, -np.inf, 1.0, 2.0]], np.float32)
    rng = np.random.default_rng(0)
    d = np.concatenate([d, rng.integers(0, 3, size=(50, 5)).astype(np.float32)])
    got = np.asarray(jax.jit(first_min)(d))
    np.testing.assert_array_equal(got, np.asarray(jnp.argmin(d, axis=1)))
    assert got.dtype == np.int32


def _tube(n, seed=0):
    """Nodes of a tube numbered ring by ring (as a mesh numbers them: lax.top_k's slow case)
    with a clot inside; a quarter of the nodes are clot nodes."""
    rng = np.random.default_rng(seed)
    n_wall = 3 * n // 4
    around = 16
    t = np.arange(n_wall)
    ring, pos = t // around, t % around
    phi = 2 * np.pi * pos / around
    wall = np.stack([0.05 * ring, np.cos(phi), np.sin(phi)], axis=1)
    m = n - n_wall
    clot = np.stack([rng.uniform(0.5, 2.0, m), *rng.uniform(-0.5, 0.5, (2, m))], axis=1)
    x = np.concatenate([wall, clot]).astype(np.float32)
    node_type = np.concatenate([np.full(n_wall, NodeType.VESSEL), np.full(m, NodeType.CLOT)])
    return x, node_type.astype(np.int32)


def test_wall_patches_and_nearest_vessel_node_as_before_on_a_numbered_tube(monkeypatch):
    """The searches of a 2,048-node tube (the pruned path), some nodes padding, against the same
    functions with the calls they replaced put back (``lax.top_k``, ``jnp.argmin``)."""
    import thrombojax.graph.wall_nodes as wall_nodes

    x, node_type = _tube(2048)
    mask = np.ones(2048, bool)
    mask[-40:] = False

    def run():  # fresh functions, so that jit traces again (no cached program)
        return [np.asarray(jax.jit(lambda *a, f=f: f(*a))(x, node_type, mask))
                for f in (wall_patches, nearest_vessel_node)]

    new = run()
    calls = []

    def top_k(key, k):
        calls.append("top_k")
        return jax.lax.top_k(-key, k)[1]

    def argmin(d):
        calls.append("argmin")
        return jnp.argmin(d, axis=1)

    monkeypatch.setattr(wall_nodes, "smallest_first", top_k)
    monkeypatch.setattr(wall_nodes, "first_min", argmin)
    old = run()
    assert "top_k" in calls and "argmin" in calls  # the old calls did run
    for a, b in zip(new, old, strict=True):
        np.testing.assert_array_equal(a, b)
    vessel = mask & (node_type == NodeType.VESSEL)
    assert np.all(vessel[new[0]]) and np.all(vessel[new[1]])
