"""Error metrics of single steps and rollouts, and the vessel-containment test.

All metrics are host-side numpy on already computed trajectories (a rollout is computed once
under ``jax.lax.scan``; measuring it is cheap). Positions may be scaled or physical: the
scaling is isotropic, so containment and centroid tests mean the same in both; MSE values
are reported in the scaled [-1, 1] coordinates, like the study's table (``PAPER.md``).

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
A clot that leaves through an open vessel end stays "inside" while it is within the tube's
extension.
"""

from __future__ import annotations

import numpy as np
from flax import struct
from scipy.spatial import cKDTree

from thrombojax.errors import DatasetError
from thrombojax.types import NodeType

__all__ = [
    "DEFAULT_HORIZONS",
    "clot_mask_of",
    "mse_per_step",
    "horizon_mse",
    "centroid_error",
    "VesselWall",
    "fit_vessel_wall",
    "signed_wall_distance",
    "fraction_outside",
]

DEFAULT_HORIZONS: tuple[int, ...] = (1, 10, 50)


def clot_mask_of(node_type: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """``[n_nodes]`` bool: real clot nodes."""
    clot = np.asarray(node_type) == NodeType.CLOT
    return clot if mask is None else clot & np.asarray(mask, bool)


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


def centroid_error(pred: np.ndarray, true: np.ndarray, clot_mask: np.ndarray) -> np.ndarray:
    """Distance between predicted and true clot centroids per frame, ``[n_steps]``."""
    sel = np.asarray(clot_mask, bool)
    c_pred = np.asarray(pred, np.float64)[:, sel].mean(axis=1)
    c_true = np.asarray(true, np.float64)[:, sel].mean(axis=1)
    return np.linalg.norm(c_pred - c_true, axis=-1)


@struct.dataclass
class VesselWall:
    """The rigid vessel wall as an oriented point cloud.

    Attributes:
        points: ``[n_wall, 3]`` wall node positions.
        normals: ``[n_wall, 3]`` outward unit normals.
        spacing: median distance between neighbouring wall nodes (scalar).
    """

    points: np.ndarray
    normals: np.ndarray
    spacing: float = struct.field(pytree_node=False)


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


def fit_vessel_wall(positions: np.ndarray, node_type: np.ndarray, *, k: int = 12) -> VesselWall:
    """Estimate outward wall normals from one frame's vessel nodes (done once: rigid vessel).

    Args:
        positions: ``[n_nodes, 3]`` one frame.
        node_type: ``[n_nodes]`` NodeType values.
        k: neighbours of the PCA normal fit.
    Returns:
        The :class:`VesselWall`.
    """
    pts = np.asarray(positions, np.float64)[np.asarray(node_type) == NodeType.VESSEL]
    if pts.shape[0] < 4:
        raise DatasetError(f"fit_vessel_wall: need >= 4 vessel nodes, got {pts.shape[0]}")
    k = min(k, pts.shape[0])
    dist, idx = cKDTree(pts).query(pts, k=k)
    spacing = float(np.median(dist[:, 1]))
    nbrs = pts[idx] - pts[idx].mean(axis=1, keepdims=True)  # [n, k, 3]
    _, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", nbrs, nbrs))
    normals = vecs[:, :, 0]  # eigenvector of the smallest eigenvalue
    normals = _orient_by_rays(pts, normals, spacing)
    return VesselWall(points=pts, normals=normals, spacing=spacing)


def signed_wall_distance(wall: VesselWall, points: np.ndarray, *, k: int = 3) -> np.ndarray:
    """Signed distance of points to the wall, positive outside: mean of ``(p - w).n_w``.

    Args:
        wall: the fitted :class:`VesselWall`.
        points: ``[..., 3]`` query points.
        k: nearest wall nodes averaged.
    Returns:
        ``[...]`` float64.
    """
    pts = np.asarray(points, np.float64)
    flat = pts.reshape(-1, 3)
    k = min(k, wall.points.shape[0])
    _, idx = cKDTree(wall.points).query(flat, k=k)
    idx = idx.reshape(flat.shape[0], k)
    s = np.einsum("nkj,nkj->nk", flat[:, None] - wall.points[idx], wall.normals[idx]).mean(1)
    return s.reshape(pts.shape[:-1])


def fraction_outside(
    wall: VesselWall,
    trajectory: np.ndarray,
    clot_mask: np.ndarray,
    *,
    tol: float | None = None,
) -> np.ndarray:
    """Fraction of clot nodes outside the vessel, per frame.

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
    return (signed_wall_distance(wall, clot) > tol).mean(axis=1)
