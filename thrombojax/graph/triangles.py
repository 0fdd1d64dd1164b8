"""Triangles (3-cliques) of an edge set, for BaryCentricSampling (the study's augmentation).

Host-side numpy (documented choice): BaryCentricSampling generates extra training samples once,
before training, so this runs outside ``jit``; the result is still returned in a bounded,
padded array with a count and an overflow flag so it can be stored with static shapes.

Conventions: the edge set is made undirected (``{i, j}`` is an edge if ``j -> i`` *or*
``i -> j`` is present; a capped radius graph is not symmetric), self loops and sentinel edges
are dropped. A triangle is listed once as ``(a, b, c)`` with ``a < b < c``, and the list is
sorted lexicographically. ``restrict_to`` keeps only triangles whose three nodes all have that
node type (e.g. ``NodeType.CLOT``: the clot's own triangles).
"""

from __future__ import annotations

import numpy as np

from thrombojax.errors import ConfigError

__all__ = ["find_triangles"]


def _edge_arrays(edges, n_nodes):
    if hasattr(edges, "indices"):  # a NeighborList
        idx = np.asarray(edges.indices)
        n = idx.shape[0]
        receivers = np.repeat(np.arange(n), idx.shape[1])
        return idx.reshape(-1), receivers, n
    senders, receivers = (np.asarray(a).reshape(-1) for a in edges)
    if n_nodes is None:
        raise ConfigError("find_triangles: pass n_nodes with a (senders, receivers) edge list")
    return senders, receivers, int(n_nodes)


def find_triangles(
    edges,
    max_triangles: int | None = None,
    *,
    n_nodes: int | None = None,
    node_type=None,
    restrict_to: int | None = None,
) -> tuple[np.ndarray, int, bool]:
    """All triangles of an undirected edge set, bounded to ``max_triangles`` rows.

    Args:
        edges: a ``NeighborList`` (``indices [N, K]``, sentinel ``N``) or a pair
            ``(senders [E], receivers [E])``; entries ``>= n_nodes`` or ``< 0`` are ignored.
        max_triangles: size ``M`` of the returned array (``None``: exactly the count).
        n_nodes: number of nodes ``N`` (needed for a senders/receivers pair).
        node_type: ``[N]`` node types (needed with ``restrict_to``).
        restrict_to: keep only triangles whose three nodes have this node type.

    Returns:
        ``(triangles [M, 3] int32, count, overflow)``: rows ``(a, b, c)``, ``a < b < c``, sorted;
        rows beyond ``count`` hold the sentinel ``N``; ``count`` is the total number found and
        ``overflow`` is True when ``count > M`` (then only the first ``M`` are returned).
    """
    s, r, n = _edge_arrays(edges, n_nodes)
    keep = (s >= 0) & (s < n) & (r >= 0) & (r < n) & (s != r)
    if restrict_to is not None:
        if node_type is None:
            raise ConfigError("find_triangles: restrict_to needs node_type")
        ok = np.asarray(node_type).reshape(-1) == restrict_to
        keep &= ok[np.clip(s, 0, n - 1)] & ok[np.clip(r, 0, n - 1)]
    lo = np.minimum(s[keep], r[keep]).astype(np.int64)
    hi = np.maximum(s[keep], r[keep]).astype(np.int64)
    keys = np.unique(lo * n + hi)  # undirected edges u < v, sorted by (u, v)
    u, v = keys // n, keys % n
    # adjacency rows of the upper-triangular graph (CSR): neighbours w > v of each v
    indptr = np.searchsorted(u, np.arange(n + 1))
    deg = indptr[v + 1] - indptr[v]
    edge_of = np.repeat(np.arange(len(keys)), deg)
    first = np.repeat(indptr[v], deg)
    offset = np.arange(len(edge_of)) - np.repeat(np.cumsum(deg) - deg, deg)
    w = v[first + offset] if len(edge_of) else np.zeros(0, np.int64)
    a, b = u[edge_of], v[edge_of]
    closing = a * n + w
    pos = np.clip(np.searchsorted(keys, closing), 0, max(len(keys) - 1, 0))
    found = (keys[pos] == closing) if len(keys) else np.zeros(0, bool)
    tri = np.stack([a[found], b[found], w[found]], axis=1).astype(np.int32)
    tri = tri[np.lexsort((tri[:, 2], tri[:, 1], tri[:, 0]))]
    count = len(tri)
    m = count if max_triangles is None else int(max_triangles)
    out = np.full((m, 3), n, np.int32)
    out[: min(m, count)] = tri[:m]
    return out, count, count > m
