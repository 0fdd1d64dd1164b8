"""Host-side construction of the :class:`~thrombojax.simulator.wall.Wall` from one frame.

Done once per simulation (the vessel is rigid), in numpy, in the coordinates of the rollout.

Triangles (``wall_cells`` given): degenerate triangles are dropped; the winding is made
consistent by a breadth-first walk over shared edges (a neighbour is flipped when it runs a
shared edge in the same direction); each connected part then gets one global sign so that its
normals point inward: the side where the clot's nodes of the first frame lie (the clot starts
inside the vessel; each clot node votes with the sign of ``(x - closest) . n`` of its nearest
triangle). A part that no clot node is nearest to is oriented by rays: from a sample of its face
centres, the side whose ray meets the wall first is inward (the ray test of the host-side
containment metric). Pseudo-normals: angle-weighted vertex normals and the sum of the two face
normals at an edge. Open ends: edges used by one triangle.

Nodes (no ``wall_cells``): the normal of a vessel node is the least-variance direction (PCA) of
its ``k`` nearest vessel nodes; the signs are made consistent along the minimum spanning tree of
the k-nearest-neighbour graph weighted by ``1 - |n_i . n_j|`` (Hoppe et al. 1992), then each
connected part is oriented by the clot vote (else rays), as above. Rim nodes (open ends): the
angular-gap test of the host-side containment metric (largest gap between neighbours > 135
degrees).
"""

from __future__ import annotations

from collections import deque

import jax.numpy as jnp
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree
from scipy.spatial import cKDTree

from thrombojax.errors import ConfigError, DatasetError
from thrombojax.simulator.wall import Wall, closest_point_on_triangle
from thrombojax.types import NodeType

__all__ = ["nearest_triangle", "wall_from_simulation"]

_SLACK_DIV = 8.0  # sagitta of an arc at mid-edge: |e| |n_a - n_b| / 8
_FAR = 1.0e4  # where padded elements sit (scaled coordinates are in [-1, 1])


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def _consistent_winding(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Flip triangles so shared edges run opposite ways.

    Returns:
        ``(tris [F, 3], part [F] connected part, edge_count [F, 3] faces at each edge)``.
    """
    n_f = len(tris)
    a = tris[:, [0, 1, 2]].reshape(-1)
    b = tris[:, [1, 2, 0]].reshape(-1)
    key = np.minimum(a, b).astype(np.int64) * (tris.max() + 1) + np.maximum(a, b)
    direction = np.where(a < b, 1, -1)
    _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    edge_count = counts[inverse].reshape(n_f, 3)
    order = np.argsort(inverse, kind="stable")
    starts = np.searchsorted(inverse[order], np.arange(counts.size))
    sign = np.zeros(n_f, np.int64)
    part = np.full(n_f, -1, np.int64)
    n_parts = 0
    for root in range(n_f):
        if sign[root]:
            continue
        sign[root], part[root] = 1, n_parts
        queue = deque([root])
        while queue:
            f = queue.popleft()
            for e in range(3 * f, 3 * f + 3):
                u = inverse[e]
                for e2 in order[starts[u]:starts[u] + counts[u]]:
                    g = e2 // 3
                    if not sign[g]:
                        sign[g] = -direction[e] * direction[e2] * sign[f]
                        part[g] = n_parts
                        queue.append(g)
        n_parts += 1
    tris = np.where((sign < 0)[:, None], tris[:, [0, 2, 1]], tris)
    return tris, part, edge_count


def nearest_triangle(points: np.ndarray, verts: np.ndarray, *, k: int = 16,
                     chunk: int = 16_384) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest triangle of each point, among the ``k`` with the nearest centroids (host, numpy).

    Args:
        points: ``[n, 3]``. verts: ``[F, 3, 3]`` triangle vertices.
        k: candidate triangles per point; chunk: points measured at once (bounds the memory).
    Returns:
        ``(face [n], closest point [n, 3], region [n])``, region as in
        :func:`thrombojax.simulator.wall.closest_point_on_triangle`.
    """
    k = min(k, len(verts))
    tree = cKDTree(verts.mean(axis=1))
    face = np.zeros(len(points), np.int64)
    point = np.zeros((len(points), 3))
    region = np.zeros(len(points), np.int32)
    for lo in range(0, len(points), chunk):
        p = points[lo:lo + chunk]
        cand = tree.query(p, k=k)[1].reshape(len(p), k)
        cv = verts[cand]  # [n, k, 3, 3]
        cp, reg = closest_point_on_triangle(p[:, None], cv[..., 0, :], cv[..., 1, :],
                                            cv[..., 2, :], xp=np)
        best = np.argmin(np.sum((p[:, None] - cp) ** 2, axis=-1), axis=1)
        rows = np.arange(len(p))
        face[lo:lo + chunk] = cand[rows, best]
        point[lo:lo + chunk] = cp[rows, best]
        region[lo:lo + chunk] = reg[rows, best]
    return face, point, region


def _ray_votes(origins, dirs, hit_dist) -> np.ndarray:
    """+1 where the ray along ``+dir`` meets the wall first, -1 along ``-dir``, 0 neither."""
    d_pos, d_neg = hit_dist(origins, dirs), hit_dist(origins, -dirs)
    return np.where(d_pos < d_neg, 1, np.where(d_neg < d_pos, -1, 0))


def _tri_hits(verts: np.ndarray, eps: float):
    """Distance along each ray to the first triangle hit (Moeller-Trumbore), inf if none."""
    a, e1, e2 = verts[:, 0], verts[:, 1] - verts[:, 0], verts[:, 2] - verts[:, 0]

    def hit_dist(o, d):
        pv = np.cross(d[:, None], e2[None])
        det = np.einsum("fk,rfk->rf", e1, pv)
        inv = 1.0 / np.where(np.abs(det) < 1e-14, np.nan, det)
        tv = o[:, None] - a[None]
        u = np.einsum("rfk,rfk->rf", tv, pv) * inv
        qv = np.cross(tv, e1[None])
        v = np.einsum("rk,rfk->rf", d, qv) * inv
        t = np.einsum("fk,rfk->rf", e2, qv) * inv
        ok = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > eps)
        return np.where(ok, t, np.inf).min(axis=1)

    return hit_dist


def _cloud_hits(points: np.ndarray, spacing: float):
    def hit_dist(o, d):
        rel = points[None] - o[:, None]
        axial = np.einsum("rnk,rk->rn", rel, d)
        perp = np.linalg.norm(rel - axial[..., None] * d[:, None], axis=-1)
        ok = (perp < 1.5 * spacing) & (axial > 2.0 * spacing)
        return np.where(ok, axial, np.inf).min(axis=1)

    return hit_dist


def _part_signs(part, votes_part, votes, origins, dirs, hit_dist, n_rays, rng) -> np.ndarray:
    """One sign per part: the clot vote where any clot node votes there, else a ray vote."""
    n_parts = part.max() + 1
    tally = np.bincount(votes_part, weights=votes, minlength=n_parts)
    signs = np.ones(n_parts)
    for p in range(n_parts):
        if tally[p] != 0:
            signs[p] = np.sign(tally[p])
            continue
        members = np.flatnonzero(part == p)
        pick = rng.choice(members, min(n_rays, members.size), replace=False)
        ray = _ray_votes(origins[pick], dirs[pick], hit_dist).sum()
        signs[p] = 1.0 if ray >= 0 else -1.0
    return signs


def _kd_order(c: np.ndarray, block_size: int) -> list[np.ndarray]:
    """Leaves of at most ``block_size`` elements: median splits along the longest extent.

    The left half of every split holds a whole number of blocks, so all leaves but the last
    are full.
    """
    leaves, stack = [], [np.arange(len(c))]
    while stack:
        idx = stack.pop()
        if len(idx) <= block_size:
            leaves.append(idx)
            continue
        pts = c[idx]
        axis = int(np.argmax(pts.max(axis=0) - pts.min(axis=0)))
        order = idx[np.argsort(pts[:, axis], kind="stable")]
        n_left = block_size * (-(-len(idx) // block_size) // 2)
        stack += [order[n_left:], order[:n_left]]
    return leaves


def _pack(fields: dict, *, kind, spacing, block_size, search_blocks, max_elements) -> Wall:
    """Group the elements into compact blocks, pad to whole blocks, compute the block boxes."""
    n = len(fields["mask"])
    leaves = _kd_order(fields["vertices"].mean(axis=1), block_size)
    size = n if max_elements is None else int(max_elements)
    if size < n:
        raise ConfigError(f"wall_from_simulation: the wall has {n} elements, more than "
                          f"max_elements={size}")
    n_blocks = max(len(leaves), -(-size // block_size))
    slots = np.full((n_blocks, block_size), -1, np.int64)
    for b, leaf in enumerate(leaves):
        slots[b, :len(leaf)] = leaf
    slots = slots.reshape(-1)
    real = slots >= 0
    out = {}
    for name, arr in fields.items():
        full = np.zeros((slots.size,) + arr.shape[1:], arr.dtype)
        if name == "vertices":
            full[:] = _FAR
        full[real] = arr[slots[real]]
        out[name] = full
    verts = out["vertices"].reshape(n_blocks, block_size * 3, 3)
    valid = np.repeat(out["mask"].reshape(n_blocks, block_size), 3, axis=1)[..., None]
    lo = np.where(valid, verts, np.inf).min(axis=1)
    hi = np.where(valid, verts, -np.inf).max(axis=1)
    empty = ~valid.any(axis=1)
    lo, hi = np.where(empty, _FAR, lo), np.where(empty, _FAR, hi)
    pad = 1e-5 * max(float(np.abs(fields["vertices"]).max()), 1.0)
    f32 = {k: jnp.asarray(v, jnp.float32 if v.dtype.kind == "f" else v.dtype)
           for k, v in out.items()}
    return Wall(**f32, block_lo=jnp.asarray(lo - pad, jnp.float32),
                block_hi=jnp.asarray(hi + pad, jnp.float32),
                spacing=jnp.asarray(spacing, jnp.float32), kind=kind, block_size=block_size,
                search_blocks=search_blocks)


def _triangle_fields(pts, tris, clot, rng, n_rays):
    a, b, c = (pts[tris[:, i]] for i in range(3))
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    edge_len = np.linalg.norm(np.stack([b - a, c - b, a - c], 1), axis=-1)
    spacing = float(np.median(edge_len))
    tris = tris[area2 > 1e-10 * spacing**2]
    if len(tris) == 0:
        raise DatasetError("wall_from_simulation: wall_cells has no non-degenerate triangle")
    tris, part, edge_count = _consistent_winding(tris)
    verts = pts[tris]  # [F, 3, 3]
    normal = _unit(np.cross(verts[:, 1] - verts[:, 0], verts[:, 2] - verts[:, 0]))
    cent = verts.mean(axis=1)
    if len(clot):
        f, cp, _ = nearest_triangle(clot, verts)
        vote = np.sign(np.einsum("nk,nk->n", clot - cp, normal[f]))
        vote_part = part[f]
    else:
        vote, vote_part = np.zeros(0), np.zeros(0, np.int64)
    signs = _part_signs(part, vote_part, vote, cent, normal, _tri_hits(verts, 1e-3 * spacing),
                        n_rays, rng)
    normal = normal * signs[part][:, None]
    # angle-weighted vertex pseudo-normals, edge pseudo-normals (sum of the adjacent faces)
    vnorm = np.zeros_like(pts)
    for i in range(3):
        e1, e2 = verts[:, (i + 1) % 3] - verts[:, i], verts[:, (i + 2) % 3] - verts[:, i]
        ang = np.arccos(np.clip(np.einsum("fk,fk->f", _unit(e1), _unit(e2)), -1, 1))
        np.add.at(vnorm, tris[:, i], ang[:, None] * normal)
    vnorm = _unit(vnorm)
    ea, eb = tris.reshape(-1), tris[:, [1, 2, 0]].reshape(-1)
    key = np.minimum(ea, eb).astype(np.int64) * (pts.shape[0] + 1) + np.maximum(ea, eb)
    _, inv = np.unique(key, return_inverse=True)
    esum = np.zeros((inv.max() + 1, 3))
    np.add.at(esum, inv, np.repeat(normal, 3, axis=0))
    enorm = _unit(esum[inv]).reshape(-1, 3, 3)
    edge_open = edge_count == 1
    vert_open = np.zeros(pts.shape[0], bool)
    vert_open[ea[edge_open.reshape(-1)]] = True
    vert_open[eb[edge_open.reshape(-1)]] = True
    vn = vnorm[tris]  # [F, 3, 3]
    el = np.linalg.norm(verts[:, [1, 2, 0]] - verts, axis=-1)
    slack = (el * np.linalg.norm(vn[:, [1, 2, 0]] - vn, axis=-1) / 8).max(axis=1)
    fields = {"vertices": verts, "face_normal": normal, "edge_normal": enorm,
              "vertex_normal": vn, "edge_open": edge_open, "vertex_open": vert_open[tris],
              "rim_dir": np.zeros_like(normal), "slack": slack, "mask": np.ones(len(tris), bool)}
    return fields, spacing


def _rim(points, normals, nbrs):
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    u = _unit(np.cross(normals, helper))
    v = np.cross(normals, u)
    rel = points[nbrs] - points[:, None]
    ang = np.sort(np.arctan2(np.einsum("nkj,nj->nk", rel, v), np.einsum("nkj,nj->nk", rel, u)))
    gaps = np.diff(np.concatenate([ang, ang[:, :1] + 2 * np.pi], axis=1), axis=1)
    widest = np.argmax(gaps, axis=1)
    rows = np.arange(points.shape[0])
    mid = ang[rows, widest] + 0.5 * gaps[rows, widest]
    direction = np.cos(mid)[:, None] * u + np.sin(mid)[:, None] * v
    is_rim = gaps[rows, widest] > 0.75 * np.pi
    return is_rim, np.where(is_rim[:, None], direction, 0.0)


def _node_fields(pts, clot, rng, n_rays, k):
    k = min(k, pts.shape[0] - 1)
    dist, idx = cKDTree(pts).query(pts, k=k + 1)
    spacing = float(np.median(dist[:, 1]))
    # weights vanishing at the (k+1)-th neighbour: ties in the neighbour ranking do not matter
    # (the normals do not depend on the orientation of the frame)
    w_pca = np.maximum(1.0 - (dist / np.maximum(dist[:, -1:], 1e-300)) ** 2, 0.0)[..., None]
    mean = (w_pca * pts[idx]).sum(axis=1, keepdims=True) / w_pca.sum(axis=1, keepdims=True)
    centred = (pts[idx] - mean) * np.sqrt(w_pca)
    normal = np.linalg.eigh(np.einsum("nki,nkj->nij", centred, centred))[1][:, :, 0]
    dist, idx = dist[:, :k], idx[:, :k]
    rows = np.repeat(np.arange(len(pts)), k - 1)
    cols = idx[:, 1:].reshape(-1)
    w = 1.0 - np.abs(np.einsum("ek,ek->e", normal[rows], normal[cols])) + 1e-9
    graph = coo_matrix((w, (rows, cols)), shape=(len(pts),) * 2).tocsr()
    tree = minimum_spanning_tree(graph + graph.T)
    tree = tree + tree.T
    n_parts, part = connected_components(tree, directed=False)
    for p in range(n_parts):
        root = int(np.flatnonzero(part == p)[0])
        order, pred = breadth_first_order(tree, root, directed=False)
        for node in order[1:]:
            if normal[node] @ normal[pred[node]] < 0:
                normal[node] = -normal[node]
    if len(clot):
        _, near = cKDTree(pts).query(clot, k=1)
        vote = np.sign(np.einsum("nk,nk->n", clot - pts[near], normal[near]))
        vote_part = part[near]
    else:
        vote, vote_part = np.zeros(0), np.zeros(0, np.int64)
    signs = _part_signs(part, vote_part, vote, pts, normal, _cloud_hits(pts, spacing), n_rays,
                        rng)
    normal = normal * signs[part][:, None]
    is_rim, rim_dir = _rim(pts, normal, idx[:, 1:])
    k_sl = min(k, 7)  # the 6 nearest, without a neighbour tied with the 7th
    n_sl = idx[:, 1:k_sl]
    near = dist[:, 1:k_sl] < dist[:, k_sl:k_sl + 1] * (1 - 1e-6) if k_sl < k else True
    slack = (np.where(near, np.linalg.norm(pts[n_sl] - pts[:, None], axis=-1), 0.0)
             * np.linalg.norm(normal[n_sl] - normal[:, None], axis=-1)).max(axis=1) / _SLACK_DIV
    n = len(pts)
    fields = {"vertices": np.repeat(pts[:, None], 3, axis=1), "face_normal": normal,
              "edge_normal": np.repeat(normal[:, None], 3, axis=1),
              "vertex_normal": np.repeat(normal[:, None], 3, axis=1),
              "edge_open": np.zeros((n, 3), bool), "vertex_open": np.repeat(is_rim[:, None], 3, 1),
              "rim_dir": rim_dir, "slack": slack, "mask": np.ones(n, bool)}
    return fields, spacing


def wall_from_simulation(
    positions0: np.ndarray,
    node_type: np.ndarray,
    wall_cells: np.ndarray | None = None,
    *,
    max_elements: int | None = None,
    block_size: int = 32,
    search_blocks: int = 8,
    k_normal: int = 12,
    n_rays: int = 32,
    seed: int = 0,
) -> Wall:
    """Build the :class:`Wall` of one simulation from one frame (host-side, numpy).

    Args:
        positions0: ``[N, 3]`` a frame of all nodes (the first: the clot must be inside), in the
            coordinates the rollout uses (scaled).
        node_type: ``[N]`` NodeType values (vessel nodes form the wall; clot nodes orient it).
        wall_cells: ``[F, 3]`` wall triangles (indices into ``positions0``, vessel nodes) or
            None: the wall is then the vessel nodes with PCA normals.
        max_elements: pad the triangles (or nodes) to this many, so walls of several
            simulations share shapes (``None``: no padding beyond a whole block).
        block_size: elements per block of the candidate search.
        search_blocks: blocks measured exactly per query point.
        k_normal: neighbours of the PCA normal and rim tests (nodes kind).
        n_rays: rays per wall part oriented by the ray test.
        seed: the sample of faces / nodes of the ray test.
    Returns:
        The :class:`Wall` (float32 arrays).
    Raises:
        DatasetError: bad shapes, cells that are not vessel nodes, too few vessel nodes.
        ConfigError: ``max_elements`` smaller than the wall, bad block sizes.
    """
    pos = np.asarray(positions0, np.float64)
    nt = np.asarray(node_type)
    if pos.ndim != 2 or pos.shape[1] != 3 or nt.shape != pos.shape[:1]:
        raise DatasetError(f"wall_from_simulation: positions0 {pos.shape} must be [N, 3] and "
                           f"node_type {nt.shape} [N]")
    if block_size < 1 or search_blocks < 1:
        raise ConfigError("wall_from_simulation: block_size and search_blocks must be >= 1")
    vessel, clot = nt == NodeType.VESSEL, pos[nt == NodeType.CLOT]
    rng = np.random.default_rng(seed)
    if wall_cells is not None and len(wall_cells):
        cells = np.asarray(wall_cells, np.int64)
        if cells.ndim != 2 or cells.shape[1] != 3:
            raise DatasetError(f"wall_from_simulation: wall_cells {cells.shape} must be [F, 3]")
        if cells.min() < 0 or cells.max() >= len(pos) or not vessel[cells].all():
            raise DatasetError("wall_from_simulation: wall_cells reference non-vessel nodes")
        fields, spacing = _triangle_fields(pos, cells, clot, rng, n_rays)
        kind = "triangles"
    else:
        if vessel.sum() < 4:
            raise DatasetError(f"wall_from_simulation: need >= 4 vessel nodes, got "
                               f"{vessel.sum()}")
        fields, spacing = _node_fields(pos[vessel], clot, rng, n_rays, k_normal)
        kind = "nodes"
    return _pack(fields, kind=kind, spacing=spacing, block_size=block_size,
                 search_blocks=search_blocks, max_elements=max_elements)
