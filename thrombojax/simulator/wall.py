"""The rigid vessel wall as a jit-ready pytree, and the exact nearest-wall-point query.

:class:`Wall` holds the wall in the coordinates of the rollout (scaled), in one of two kinds:

* ``"triangles"`` (the dataset has ``wall_cells``): the wall triangles, wound consistently and
  oriented on the host (:mod:`thrombojax.simulator.wall_build`) so that their normals point
  *inward* (to the clot's side). The query is the exact point-triangle distance (closest point
  on a triangle by its Voronoi regions, Ericson, *Real-Time Collision Detection*, 5.1.5); inside
  or outside is the sign of ``(x - closest) . n`` with the angle-weighted *pseudo-normal* ``n``
  of the closest feature (face, edge or vertex; Baerentzen & Aanaes 2005), which is the exact
  sign test for a closed mesh and reduces to the face normal inside a face.
* ``"nodes"`` (no ``wall_cells``): the wall nodes with inward unit normals; the signed distance
  of ``x`` is a weighted mean over its ``K_AVG`` nearest wall nodes ``w`` of ``(w - x) . n_w`` (the
  tangent-plane distance, positive outside, as the host-side containment metric),
  weighted by ``1/d_j^2 - 1/d_{K+1}^2`` (Shepard weights that vanish at the next node, so the
  distance is continuous in ``x``), and its nearest wall point is ``x + s n`` with ``n`` the
  normalised weighted normal.

Open ends: a node whose closest wall feature lies on an open boundary of the wall (a rim edge
or rim vertex of the triangles; a rim node of the cloud, beyond it along its rim direction) is
*past the end*: the clot left through the vessel's outlet and is not outside.

Slack: the triangles are chords of a smooth vessel whose vertices lie on it, so the true wall
bulges outward of a face by up to ``slack = max_edges |e| |n_a - n_b| / 8`` (the sagitta of a
circular arc through the edge with the vertex normals ``n_a, n_b``). Points within the slack of
a face are not outside. A wall node's slack is the same formula over its 6 nearest wall nodes
(where the wall is saddle-shaped, e.g. the inner side of a bend, it lies outside the tangent
plane); the query uses the mean slack of the ``K_AVG`` nodes.

Candidate search (static shapes, nothing dropped silently): elements (triangles or nodes) are
grouped on the host into compact blocks of ``block_size`` (the leaves of median splits along
the longest extent), each with its bounding box. A query ranks the blocks by the distance to
their box (a lower bound of the distance to anything inside; ties inside boxes broken by the
distance to the box centre), keeps the ``search_blocks`` best and measures every element in them
exactly. The answer is *certified* (``WallQuery.certain``) when the distance found is at most the
smallest box distance of the blocks left out: no element outside the candidates can be nearer.
A wall with at most ``search_blocks`` blocks is always searched exhaustively.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

__all__ = [
    "Wall",
    "WallQuery",
    "K_AVG",
    "nearest_wall_point",
    "closest_point_on_triangle",
    "safe_norm",
]

K_AVG: int = 3
"""Wall nodes averaged by the ``"nodes"`` kind (as the host-side containment metric)."""


@struct.dataclass
class Wall:
    """The rigid wall (a pytree; fixed, padded shapes). ``F`` elements in ``B`` blocks.

    Attributes:
        vertices: ``[F, 3, 3]`` triangle vertices (``"nodes"``: the node three times).
        face_normal: ``[F, 3]`` inward unit normal of the face (``"nodes"``: of the node).
        edge_normal: ``[F, 3, 3]`` inward pseudo-normals of edges (v0v1, v1v2, v2v0).
        vertex_normal: ``[F, 3, 3]`` inward pseudo-normals of the three vertices.
        edge_open: ``[F, 3]`` bool, the edge lies on an open end of the wall.
        vertex_open: ``[F, 3]`` bool, the vertex lies on an open end (``"nodes"``: rim node).
        rim_dir: ``[F, 3]`` ``"nodes"`` only: unit in-surface direction out of the wall at rim
            nodes, zero elsewhere (zeros for triangles).
        slack: ``[F]`` outward bulge of the smooth wall beyond the face (or node plane).
        mask: ``[F]`` bool, real elements (padding is False and far away).
        block_lo: ``[B, 3]`` lower corners of the blocks' bounding boxes.
        block_hi: ``[B, 3]`` upper corners.
        spacing: ``[]`` median wall edge length (nodes: nearest-neighbour distance).
        kind: ``"triangles"`` or ``"nodes"`` (static).
        block_size: elements per block (static); ``F = B * block_size``.
        search_blocks: blocks measured per query (static).
    """

    vertices: jax.Array
    face_normal: jax.Array
    edge_normal: jax.Array
    vertex_normal: jax.Array
    edge_open: jax.Array
    vertex_open: jax.Array
    rim_dir: jax.Array
    slack: jax.Array
    mask: jax.Array
    block_lo: jax.Array
    block_hi: jax.Array
    spacing: jax.Array
    kind: str = struct.field(pytree_node=False, default="triangles")
    block_size: int = struct.field(pytree_node=False, default=32)
    search_blocks: int = struct.field(pytree_node=False, default=8)

    @property
    def n_blocks(self) -> int:
        return self.block_lo.shape[-2]


@struct.dataclass
class WallQuery:
    """Nearest wall point of each query point.

    Attributes:
        point: ``[N, 3]`` nearest point of the wall.
        normal: ``[N, 3]`` inward unit normal there (pseudo-normal of the closest feature).
        signed: ``[N]`` signed distance, positive outside the wall.
        distance: ``[N]`` ``|x - point|``.
        slack: ``[N]`` the slack of the nearest element (nodes: mean of the ``K_AVG``).
        past_end: ``[N]`` bool, beyond an open end of the wall (not outside).
        certain: ``[N]`` bool, the nearest element is certified (see the module docstring).
    """

    point: jax.Array
    normal: jax.Array
    signed: jax.Array
    distance: jax.Array
    slack: jax.Array
    past_end: jax.Array
    certain: jax.Array


def _dot(a, b):
    return jnp.sum(a * b, axis=-1)


def safe_norm(v: jax.Array, axis: int = -1, keepdims: bool = False) -> jax.Array:
    """Euclidean norm, exactly 0 for a zero vector, with a zero (not NaN) gradient there."""
    sq = jnp.sum(v * v, axis=axis, keepdims=keepdims)
    pos = sq > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, sq, 1.0)), 0.0)


def closest_point_on_triangle(p, a, b, c, xp=jnp):
    """Closest point of triangles ``(a, b, c)`` to points ``p`` (broadcasting ``[..., 3]``).

    Args:
        p, a, b, c: ``[..., 3]`` points and triangle vertices.
        xp: the array module (``jax.numpy``; ``numpy`` for host-side use).
    Returns:
        ``(point [..., 3], region [...] int32)``: region 0 face, 1/2/3 vertex a/b/c,
        4/5/6 edge ab/bc/ca (Ericson's Voronoi-region test, exact zeros off the face).
    """
    def dot(u, v):
        return xp.sum(u * v, axis=-1)

    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp = p - b
    d3, d4 = dot(ab, bp), dot(ac, bp)
    cp = p - c
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2

    def safe(num, den):
        return num / xp.where(den == 0, 1.0, den)

    denom = va + vb + vc
    v_f, w_f = safe(vb, denom), safe(vc, denom)
    point = a + v_f[..., None] * ab + w_f[..., None] * ac
    region = xp.zeros(va.shape, xp.int32)
    # cases from the lowest to the highest priority of Ericson's early returns
    cases = [
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), 5,
         b + safe(d4 - d3, (d4 - d3) + (d5 - d6))[..., None] * (c - b)),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), 6, a + safe(d2, d2 - d6)[..., None] * ac),
        ((d6 >= 0) & (d5 <= d6), 3, c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), 4, a + safe(d1, d1 - d3)[..., None] * ab),
        ((d3 >= 0) & (d4 <= d3), 2, b),
        ((d1 <= 0) & (d2 <= 0), 1, a),
    ]
    for cond, code, pt in cases:
        point = xp.where(cond[..., None], xp.broadcast_to(pt, point.shape), point)
        region = xp.where(cond, code, region)
    return point, region


def _candidates(x, wall: Wall):
    """Indices ``[N, C]`` of the candidate elements and the lower bound ``[N]`` left out."""
    gap = jnp.maximum(jnp.maximum(wall.block_lo[None] - x[:, None], x[:, None]
                                  - wall.block_hi[None]), 0.0)
    lower = jnp.linalg.norm(gap, axis=-1)  # [N, B] distance to each block's box
    n_blocks, kb = wall.n_blocks, wall.search_blocks
    if n_blocks <= kb:
        blocks = jnp.broadcast_to(jnp.arange(n_blocks), (x.shape[0], n_blocks))
        left_out = jnp.full(x.shape[:1], jnp.inf, x.dtype)
    else:
        # ties (points inside several boxes) are broken by the distance to the box centre
        centre = 0.5 * (wall.block_lo + wall.block_hi)
        key = lower + 1e-3 * jnp.linalg.norm(x[:, None] - centre[None], axis=-1)
        _, blocks = jax.lax.top_k(-key, kb)
        chosen = jnp.zeros(lower.shape, bool).at[jnp.arange(x.shape[0])[:, None], blocks].set(True)
        left_out = jnp.min(jnp.where(chosen, jnp.inf, lower), axis=1)
    elems = blocks[:, :, None] * wall.block_size + jnp.arange(wall.block_size)
    return elems.reshape(x.shape[0], -1), left_out


def _query_triangles(x, wall: Wall) -> WallQuery:
    idx, left_out = _candidates(x, wall)  # [N, C]
    tri = wall.vertices[idx]  # [N, C, 3, 3]
    pts, region = closest_point_on_triangle(x[:, None], tri[..., 0, :], tri[..., 1, :],
                                            tri[..., 2, :])
    d2 = jnp.sum((x[:, None] - pts) ** 2, axis=-1)
    d2 = jnp.where(wall.mask[idx], d2, jnp.inf)
    best = jnp.argmin(d2, axis=1)
    rows = jnp.arange(x.shape[0])
    f, reg, point = idx[rows, best], region[rows, best], pts[rows, best]
    normals = jnp.concatenate(
        [wall.face_normal[f][:, None], wall.vertex_normal[f], wall.edge_normal[f]], axis=1
    )  # [N, 7, 3] in region order: face, vertex a/b/c, edge ab/bc/ca
    normal = normals[rows, reg]
    opens = jnp.concatenate(
        [jnp.zeros_like(wall.edge_open[f][:, :1]), wall.vertex_open[f], wall.edge_open[f]], axis=1
    )
    diff = x - point
    distance = safe_norm(diff)
    signed = jnp.where(_dot(diff, normal) > 0, -distance, distance)
    certain = distance <= left_out
    return WallQuery(point=point, normal=normal, signed=signed, distance=distance,
                     slack=wall.slack[f], past_end=opens[rows, reg], certain=certain)


def _query_nodes(x, wall: Wall) -> WallQuery:
    idx, left_out = _candidates(x, wall)
    w = wall.vertices[idx, 0]  # [N, C, 3]
    d2 = jnp.where(wall.mask[idx], jnp.sum((x[:, None] - w) ** 2, axis=-1), jnp.inf)
    k = min(K_AVG + 1, idx.shape[1])
    neg, near = jax.lax.top_k(-d2, k)  # nearest first
    j = jnp.take_along_axis(idx, near, axis=1)  # [N, k]
    wj, nj = wall.vertices[j, 0], wall.face_normal[j]
    # Shepard weights vanishing at the (K_AVG + 1)-th node: continuous when neighbours swap
    inv = 1.0 / jnp.maximum(-neg, 1e-12)
    weight = jnp.maximum(inv - inv[:, -1:], 0.0) if k > 1 else inv
    weight = jnp.where(jnp.isinf(neg[:, :1]), 0.0, weight)
    weight = weight / jnp.maximum(jnp.sum(weight, axis=1, keepdims=True), 1e-30)
    signed = jnp.sum(weight * _dot(wj - x[:, None], nj), axis=1)
    mean_n = jnp.sum(weight[..., None] * nj, axis=1)
    normal = mean_n / jnp.maximum(jnp.linalg.norm(mean_n, axis=-1, keepdims=True), 1e-12)
    point = x + signed[:, None] * normal
    j0 = j[:, 0]
    past = wall.vertex_open[j0, 0] & (_dot(x - wall.vertices[j0, 0], wall.rim_dir[j0]) > 0)
    certain = jnp.sqrt(-neg[:, -1]) <= left_out
    return WallQuery(point=point, normal=normal, signed=signed, distance=jnp.abs(signed),
                     slack=jnp.sum(weight * wall.slack[j], axis=1), past_end=past, certain=certain)


def nearest_wall_point(x: jax.Array, wall: Wall, *, tile_rows: int = 512) -> WallQuery:
    """The nearest wall point, inward normal and signed distance of every point. Jittable.

    Args:
        x: ``[N, 3]`` points, in the wall's coordinates.
        wall: the :class:`Wall`.
        tile_rows: rows measured at once (``lax.map`` over tiles bounds the memory to
            ``tile_rows x search_blocks x block_size`` candidates); static.
    Returns:
        The :class:`WallQuery`, every field with leading dimension ``N``.
    """
    query = _query_triangles if wall.kind == "triangles" else _query_nodes
    n = x.shape[0]
    if n <= tile_rows:
        return query(x, wall)
    n_tiles = -(-n // tile_rows)
    xp = jnp.concatenate([x, jnp.broadcast_to(x[:1], (n_tiles * tile_rows - n, 3))])
    out = jax.lax.map(lambda xt: query(xt, wall), xp.reshape(n_tiles, tile_rows, 3))
    return jax.tree.map(lambda a: a.reshape((n_tiles * tile_rows,) + a.shape[2:])[:n], out)
