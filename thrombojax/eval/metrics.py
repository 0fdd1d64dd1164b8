"""Error metrics of single steps and rollouts, and the vessel-containment test.

All metrics are host-side numpy on already computed trajectories (a rollout is computed once
under ``jax.lax.scan``; measuring it is cheap). Positions may be scaled or physical: the
scaling is isotropic, so containment and centroid tests mean the same in both; MSE values
are computed in the scaled [-1, 1] coordinates, like the study's table (reports convert them to
vessel radii, :mod:`thrombojax.eval.physical`).

Conventions (following DeepMind ``meshgraphnets`` evaluators):
- ``mse_per_step[k]`` is the mean over clot nodes and x, y, z of the squared error of
  predicted frame ``t0 + k + 1``.
- ``mse@h`` is the mean of ``mse_per_step`` over the first ``h`` steps; horizons longer than
  the rollout are not reported (the table shows them as "n/a"); ``mse@full`` uses every step.

Containment ("outside the vessel"): the vessel is only a cloud of wall nodes (imported data
has no centreline), so we estimate an outward unit normal per wall node once (PCA of its
nearest wall neighbours, oriented by a ray test: the inward side is the side whose ray
meets the opposite wall first) and call a clot node *outside* when its signed distance
``(p - w) . n_w``, averaged over its 3 nearest wall nodes, exceeds ``tol`` (default half
the median wall-node spacing, so contact penetration at solver precision does not count).
A clot node past an open vessel end is not outside: the clot left through the outlet. With
wall triangles (``wall_cells``) a node is past an open end when its nearest point on the wall
mesh lies on an open (one-triangle) edge or a rim vertex: the test the rollout's guards use
(``past_end`` of :func:`thrombojax.simulator.wall.nearest_wall_point`), so the two agree on
which nodes left. Without triangles, when its nearest wall node is on the rim (detected as a
one-sided neighbourhood) and it lies beyond it.
"""

from __future__ import annotations

import numpy as np
from flax import struct
from scipy.spatial import cKDTree

from thrombojax.errors import DatasetError
from thrombojax.simulator.wall_build import nearest_triangle
from thrombojax.types import NodeType

__all__ = [
    "DEFAULT_HORIZONS",
    "mse_per_step",
    "horizon_mse",
    "clot_centroids",
    "centroid_error",
    "VesselWall",
    "fit_vessel_wall",
    "signed_wall_distance",
    "fraction_outside",
]

DEFAULT_HORIZONS: tuple[int, ...] = (1, 10, 50)


def mse_per_step(pred: np.ndarray, true: np.ndarray, clot_mask: np.ndarray) -> np.ndarray:
    """Squared error over clot nodes and axes, per frame.

    Args:
        pred, true: ``[n_steps, n_nodes, 3]`` positions (scaled coordinates).
        clot_mask: ``[n_nodes]`` bool, the nodes that count.
    Returns:
        ``[n_steps]`` float64 MSE.
    """
    pred, true = np.asarray(pred, np.float64), np.asarray(true, np.float64)
    if pred.shape != true.shape:
        raise DatasetError(f"mse_per_step: shapes differ, prediction {pred.shape} vs {true.shape}")
    sel = np.asarray(clot_mask, bool)
    return ((pred[:, sel] - true[:, sel]) ** 2).mean(axis=(1, 2))


def horizon_mse(
    per_step: np.ndarray, horizons: tuple[int, ...] = DEFAULT_HORIZONS
) -> dict[str, float]:
    """Mean rollout MSE over the first ``h`` steps for each horizon, plus ``mse@full``.

    Args:
        per_step: ``[n_steps]`` MSE per predicted step.
        horizons: horizons in steps; those longer than ``n_steps`` are left out.
    Returns:
        ``{"mse@1": ..., "mse@10": ..., "mse@full": ...}``.
    """
    per_step = np.asarray(per_step, np.float64)
    out = {f"mse@{h}": float(per_step[:h].mean()) for h in horizons if h <= per_step.size}
    out["mse@full"] = float(per_step.mean())
    return out


def clot_centroids(frames: np.ndarray, clot_mask: np.ndarray) -> np.ndarray:
    """The clot's centroid in every frame, ``[T, 3]`` (float64)."""
    return np.asarray(frames, np.float64)[:, np.asarray(clot_mask, bool)].mean(axis=1)


def centroid_error(pred: np.ndarray, true: np.ndarray, clot_mask: np.ndarray) -> np.ndarray:
    """Distance between predicted and true clot centroids per frame, ``[n_steps]``."""
    return np.linalg.norm(clot_centroids(pred, clot_mask) - clot_centroids(true, clot_mask),
                          axis=-1)


@struct.dataclass
class VesselWall:
    """The rigid vessel wall as an oriented point cloud.

    Attributes:
        points: ``[n_wall, 3]`` wall node positions.
        normals: ``[n_wall, 3]`` outward unit normals.
        rim_dir: ``[n_wall, 3]`` for nodes on an open end of the vessel (the rim), the unit
            in-surface direction pointing out of the wall; zero elsewhere.
        spacing: median distance between neighbouring wall nodes (scalar).
        cells: ``[F, 3]`` wall triangles (indices into ``points``) when the data has them, else
            ``None``.
        open_feature: ``[F, 7]`` bool with ``cells``: whether each closest-point region of a
            triangle (face, vertex a / b / c, edge ab / bc / ca, the order of
            :func:`thrombojax.simulator.wall.closest_point_on_triangle`) lies on an open end.
    """

    points: np.ndarray
    normals: np.ndarray
    rim_dir: np.ndarray
    spacing: float = struct.field(pytree_node=False)
    cells: np.ndarray | None = None
    open_feature: np.ndarray | None = None


def _orient_by_rays(points: np.ndarray, normals: np.ndarray, spacing: float) -> np.ndarray:
    """Flip each normal so that the opposite wall lies on its negative (inward) side."""
    n = points.shape[0]
    sign = np.ones(n)
    chunk = max(1, 4_000_000 // max(n, 1))
    for lo in range(0, n, chunk):
        d = points[None] - points[lo:lo + chunk, None]  # [c, n, 3]
        axial = np.einsum("cnk,ck->cn", d, normals[lo:lo + chunk])
        perp = np.linalg.norm(d - axial[..., None] * normals[lo:lo + chunk, None], axis=-1)
        hit = (perp < 1.5 * spacing) & (np.abs(axial) > 2.0 * spacing)
        pos = np.where(hit & (axial > 0), axial, np.inf).min(axis=1)
        neg = np.where(hit & (axial < 0), -axial, np.inf).min(axis=1)
        # the inward ray meets the opposite wall first: flip when that is the +n side
        sign[lo:lo + chunk] = np.where(pos < neg, -1.0, 1.0)
    return normals * sign[:, None]


def _orient(points: np.ndarray, normals: np.ndarray, spacing: float, max_rays: int,
            seed: int = 0) -> np.ndarray:
    """Ray-test orientation on at most ``max_rays`` wall nodes, copied to the others.

    Large walls (ClotEntry: ~20,000 nodes) orient a random subset by rays (quadratic cost), and
    every other node takes the sign that aligns its normal with its nearest oriented node.
    """
    n = points.shape[0]
    if n <= max_rays:
        return _orient_by_rays(points, normals, spacing)
    sub = np.sort(np.random.default_rng(seed).choice(n, max_rays, replace=False))
    sub_spacing = spacing * np.sqrt(n / max_rays)  # same surface, fewer points
    oriented = _orient_by_rays(points[sub], normals[sub], sub_spacing)
    _, near = cKDTree(points[sub]).query(points, k=1)
    flip = np.einsum("nk,nk->n", normals, oriented[near]) < 0
    return np.where(flip[:, None], -normals, normals)


def _rim_directions(points: np.ndarray, normals: np.ndarray, nbrs: np.ndarray) -> np.ndarray:
    """Boundary (open vessel end) detection by the angular-gap test of point-cloud boundaries.

    The neighbours of a node, projected onto its tangent plane, surround it on the wall but
    leave a gap of about 180 degrees on a rim. A node whose largest angular gap exceeds 135
    degrees is a rim node; its direction is the bisector of that gap.

    Returns:
        ``[n, 3]`` unit in-plane direction out of the wall on rim nodes, zero elsewhere.
    """
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    u = np.cross(normals, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(normals, u)
    rel = points[nbrs] - points[:, None]  # [n, k, 3]
    ang = np.sort(np.arctan2(np.einsum("nkj,nj->nk", rel, v), np.einsum("nkj,nj->nk", rel, u)))
    gaps = np.diff(np.concatenate([ang, ang[:, :1] + 2 * np.pi], axis=1), axis=1)
    widest = np.argmax(gaps, axis=1)
    rows = np.arange(points.shape[0])
    mid = ang[rows, widest] + 0.5 * gaps[rows, widest]
    direction = np.cos(mid)[:, None] * u + np.sin(mid)[:, None] * v
    return np.where((gaps[rows, widest] > 0.75 * np.pi)[:, None], direction, 0.0)


def _mesh_normals_and_rim(pts: np.ndarray, tris: np.ndarray):
    """Area-weighted vertex normals (unoriented), rim directions and open features ``[F, 7]``."""
    a, b, c = (pts[tris[:, i]] for i in range(3))
    face = np.cross(b - a, c - a)  # length = 2 x area
    normals = np.zeros_like(pts)
    for i in range(3):
        np.add.at(normals, tris[:, i], face)
    # boundary edges: used by one triangle; direction away from the triangle's third vertex
    edges = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    third = np.concatenate([tris[:, 2], tris[:, 0], tris[:, 1]])
    key = np.sort(edges, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = counts[inverse.ravel()] == 1
    e, t = edges[boundary], third[boundary]
    mid = 0.5 * (pts[e[:, 0]] + pts[e[:, 1]])
    rim = np.zeros_like(pts)
    for i in range(2):
        np.add.at(rim, e[:, i], mid - pts[t])
    on_rim = np.zeros(pts.shape[0], bool)
    on_rim[e.ravel()] = True
    edge_open = boundary.reshape(3, -1).T  # [F, 3]: ab, bc, ca
    open_feature = np.concatenate([np.zeros((len(tris), 1), bool), on_rim[tris], edge_open], 1)
    return normals, rim, open_feature


def fit_vessel_wall(
    positions: np.ndarray,
    node_type: np.ndarray,
    *,
    wall_cells: np.ndarray | None = None,
    k: int = 12,
    max_rays: int = 3000,
) -> VesselWall:
    """Estimate outward wall normals from one frame's vessel nodes (done once: rigid vessel).

    Args:
        positions: ``[n_nodes, 3]`` one frame.
        node_type: ``[n_nodes]`` NodeType values.
        wall_cells: ``[F, 3]`` wall triangles (node indices of ``positions``) when the data has
            them: normals and open ends then come from the mesh; else from the point cloud
            (PCA normals, angular-gap rim test).
        k: neighbours of the PCA normal fit.
        max_rays: wall nodes oriented by the ray test (the others copy their neighbour's).
    Returns:
        The :class:`VesselWall`.
    """
    vessel = np.asarray(node_type) == NodeType.VESSEL
    pts = np.asarray(positions, np.float64)[vessel]
    if pts.shape[0] < 4:
        raise DatasetError(f"fit_vessel_wall: need >= 4 vessel nodes, got {pts.shape[0]}")
    k = min(k, pts.shape[0])
    dist, idx = cKDTree(pts).query(pts, k=k)
    spacing = float(np.median(dist[:, 1]))
    if wall_cells is not None and len(wall_cells):
        remap = np.full(vessel.size, -1, np.int64)
        remap[vessel] = np.arange(pts.shape[0])
        tris = remap[np.asarray(wall_cells)]
        if (tris < 0).any():
            raise DatasetError("fit_vessel_wall: wall_cells reference non-vessel nodes")
        normals, rim, open_feature = _mesh_normals_and_rim(pts, tris)
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        normals = _orient(pts, normals, spacing, max_rays)
        rim -= np.einsum("nk,nk->n", rim, normals)[:, None] * normals
        rim_dir = rim / np.maximum(np.linalg.norm(rim, axis=1, keepdims=True), 1e-12)
        return VesselWall(points=pts, normals=normals, rim_dir=rim_dir, spacing=spacing,
                          cells=tris, open_feature=open_feature)
    nbrs = pts[idx] - pts[idx].mean(axis=1, keepdims=True)  # [n, k, 3]
    _, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", nbrs, nbrs))
    normals = vecs[:, :, 0]  # eigenvector of the smallest eigenvalue
    normals = _orient(pts, normals, spacing, max_rays)
    rim_dir = _rim_directions(pts, normals, idx[:, 1:])
    return VesselWall(points=pts, normals=normals, rim_dir=rim_dir, spacing=spacing)


def signed_wall_distance(
    wall: VesselWall, points: np.ndarray, *, k: int = 3, return_past_end: bool = False
):
    """Signed distance of points to the wall, positive outside: mean of ``(p - w).n_w``.

    Args:
        wall: the fitted :class:`VesselWall`.
        points: ``[..., 3]`` query points.
        k: nearest wall nodes averaged.
        return_past_end: also return whether each point lies past an open vessel end (module
            docstring: from the wall triangles when the wall has them).
    Returns:
        ``[...]`` float64, and ``[...]`` bool when ``return_past_end``.
    """
    pts = np.asarray(points, np.float64)
    flat = pts.reshape(-1, 3)
    k = min(k, wall.points.shape[0])
    _, idx = cKDTree(wall.points).query(flat, k=k)
    idx = idx.reshape(flat.shape[0], k)
    s = np.einsum("nkj,nkj->nk", flat[:, None] - wall.points[idx], wall.normals[idx]).mean(1)
    if not return_past_end:
        return s.reshape(pts.shape[:-1])
    if wall.cells is not None:  # as the guards decide it: nearest mesh point on an open feature
        face, _, region = nearest_triangle(flat, wall.points[wall.cells])
        past = wall.open_feature[face, region]
    else:
        near = idx[:, 0]
        past = np.einsum("nj,nj->n", flat - wall.points[near], wall.rim_dir[near]) > 0
    return s.reshape(pts.shape[:-1]), past.reshape(pts.shape[:-1])


def fraction_outside(
    wall: VesselWall,
    trajectory: np.ndarray,
    clot_mask: np.ndarray,
    *,
    tol: float | None = None,
) -> np.ndarray:
    """Fraction of clot nodes outside the vessel (through its wall), per frame.

    Nodes past an open end of the vessel (a clot leaving through the outlet, free to expand)
    do not count as outside.

    Args:
        wall: the fitted :class:`VesselWall` (same coordinates as ``trajectory``).
        trajectory: ``[n_steps, n_nodes, 3]``.
        clot_mask: ``[n_nodes]`` bool.
        tol: signed-distance threshold; default ``0.5 * wall.spacing``.
    Returns:
        ``[n_steps]`` float in [0, 1].
    """
    tol = 0.5 * wall.spacing if tol is None else tol
    clot = np.asarray(trajectory)[:, np.asarray(clot_mask, bool)]
    out = signed_wall_distance(wall, clot) > tol
    if out.any():  # the open-end test only where it can matter
        out[out] = ~signed_wall_distance(wall, clot[out], return_past_end=True)[1]
    return out.mean(axis=1)
