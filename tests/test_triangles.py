"""Triangles of an edge set: brute force, node-type restriction, bound and overflow."""

import itertools

import jax
import numpy as np
import pytest

from thrombojax.errors import ConfigError
from thrombojax.graph import find_triangles, radius_graph, senders_receivers


def brute_force(ids, n, keep=None):
    adj = np.zeros((n, n), bool)
    for i in range(n):
        for j in ids[i]:
            if j < n and j != i:
                adj[i, j] = adj[j, i] = True
    ok = np.ones(n, bool) if keep is None else keep
    return [
        t
        for t in itertools.combinations(range(n), 3)
        if ok[list(t)].all() and adj[t[0], t[1]] and adj[t[1], t[2]] and adj[t[0], t[2]]
    ]


@pytest.fixture(scope="module")
def graph():
    x = np.random.default_rng(0).uniform(-1, 1, (80, 3)).astype(np.float32)
    return jax.jit(lambda p: radius_graph(p, 0.5, 6))(x)


def test_matches_brute_force(graph):
    tri, count, overflow = find_triangles(graph)
    want = brute_force(np.asarray(graph.indices), 80)
    assert count == len(want) > 10 and not overflow
    assert tri.dtype == np.int32 and tri.shape == (count, 3)
    assert [tuple(t) for t in tri] == want  # a < b < c, sorted


def test_senders_receivers_input_restriction_and_bound(graph):
    node_type = np.random.default_rng(1).integers(0, 2, 80)
    s, r, _ = senders_receivers(graph)
    want = brute_force(np.asarray(graph.indices), 80, keep=node_type == 1)
    tri, count, overflow = find_triangles(
        (s, r), 64, n_nodes=80, node_type=node_type, restrict_to=1
    )
    assert count == len(want) and not overflow and tri.shape == (64, 3)
    assert [tuple(t) for t in tri[:count]] == want and np.all(tri[count:] == 80)
    tri, count2, overflow = find_triangles(graph, 2)
    assert overflow and count2 > 2 and tri.shape == (2, 3)
    with pytest.raises(ConfigError):
        find_triangles((s, r))
    with pytest.raises(ConfigError):
        find_triangles(graph, restrict_to=1)


def test_no_edges():
    tri, count, overflow = find_triangles((np.array([3]), np.array([3])), 4, n_nodes=3)
    assert count == 0 and not overflow and np.all(tri == 3)
