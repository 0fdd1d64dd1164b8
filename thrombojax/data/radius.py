"""The vessel radius of a dataset, in the dataset's own length unit: the length errors are read in.

An error of 0.01 scaled units means nothing to a clinician; "a tenth of a vessel radius" does.
:func:`vessel_radius` gives the radius ``r`` (in the unit of the dataset's positions) that every
evaluation report divides lengths by, from the first of:

1. the file attribute ``vessel_radius`` (a positive number, set by whoever knows it);
2. ``1.0`` when the file attribute ``units`` is ``"vessel radius"`` (the built-in solver writes
   its coordinates in vessel radii, ``thrombojax/sim/presets.py``);
3. an estimate from the geometry, :func:`estimate_vessel_radius` on frame 0 of each simulation
   (at most ``max_sims`` of them), median over simulations.

The estimate (wall only; the clot may start inside or outside the vessel): for each wall node
(at most ``max_rays``, a seeded subset) fit the wall's normal line (PCA of its ``k`` nearest wall
nodes), follow that line through the lumen and take the distance to the first wall node met on
the far side (the local diameter); ``r`` = half the median over nodes. The median ignores the
minority of lines that leave through an open end, meet a neighbouring loop of a tortuous vessel,
or cross a flared outlet; where the radius varies along the vessel it is the median lumen
radius. Measured: 1.00 on the built-in BendVessel walls (radius 1), 0.98-1.00 on frame 0 of
``bendvessel-tiny`` and ``clotentry-tiny`` solver data, 1.09 on ClotEntry walls (radius tapering
1.0 -> 1.18, median 1.09), within 3 % on synthetic straight and bent tubes of any radius
(tests/test_radius.py). A clot-based alternative (largest distance of a frame-0 clot node to its
nearest wall node) was measured too and rejected: it needs the clot inside the lumen at frame 0
and overestimates by up to half the wall-node spacing.

Host-side numpy and scipy only (called once per evaluation).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from thrombojax.errors import DatasetError
from thrombojax.types import NodeType

__all__ = [
    "RADIUS_UNITS",
    "estimate_vessel_radius",
    "vessel_radius_and_source",
    "vessel_radius",
]

RADIUS_UNITS = "vessel radius"
"""The ``units`` attribute of a dataset whose coordinates are already in vessel radii."""


def _normal_lines(pts: np.ndarray, k: int) -> tuple[np.ndarray, float]:
    """Unit normal (unoriented) of every wall node by PCA of its neighbours; a wall spacing.

    Returns:
        ``([n, 3] normals, spacing)``, spacing = median distance to the 4th nearest wall node
        (wider than the nearest one, so the line test below also meets nodes on coarse rings).
    """
    k = min(k, pts.shape[0])
    dist, idx = cKDTree(pts).query(pts, k=k)
    nbrs = pts[idx] - pts[idx].mean(axis=1, keepdims=True)  # [n, k, 3]
    _, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", nbrs, nbrs))
    return vecs[:, :, 0], float(np.median(dist[:, min(4, k - 1)]))


def estimate_vessel_radius(
    positions: np.ndarray,
    node_type: np.ndarray,
    *,
    k: int = 12,
    max_rays: int = 512,
    seed: int = 0,
) -> float:
    """Estimate the vessel radius of one frame from its wall nodes (module docstring).

    Args:
        positions: ``[N, 3]`` one frame, any length unit.
        node_type: ``[N]`` NodeType values; the ``VESSEL`` nodes are the wall.
        k: wall neighbours of the normal fit.
        max_rays: wall nodes whose diameter line is measured (a seeded subset beyond that).
        seed: subset seed.
    Returns:
        The radius, in the unit of ``positions``.
    Raises:
        DatasetError: fewer than 8 wall nodes, or no normal line meets the opposite wall.
    """
    pts = np.asarray(positions, np.float64)[np.asarray(node_type) == NodeType.VESSEL]
    if pts.shape[0] < 8:
        raise DatasetError(f"estimate_vessel_radius: need >= 8 vessel nodes, got {pts.shape[0]}")
    normals, spacing = _normal_lines(pts, k)
    rays = np.arange(pts.shape[0])
    if rays.size > max_rays:
        rays = np.sort(np.random.default_rng(seed).choice(rays.size, max_rays, replace=False))
    diameters = []
    chunk = max(1, 2_000_000 // pts.shape[0])
    for lo in range(0, rays.size, chunk):
        r = rays[lo:lo + chunk]
        d = pts[None] - pts[r, None]  # [c, n, 3]
        axial = np.einsum("cnk,ck->cn", d, normals[r])
        perp = np.linalg.norm(d - axial[..., None] * normals[r, None], axis=-1)
        dist = np.abs(axial)
        # nodes near the line, past the node's own (curving) surface: the far walls
        far = (perp < 1.5 * spacing) & (dist > spacing)
        first = np.where(far, dist, np.inf).min(axis=1)  # [c] the nearest far wall
        # of the far-wall nodes near that crossing, the one closest to the line
        near = far & (dist < first[:, None] + 1.5 * spacing)
        best = np.argmin(np.where(near, perp, np.inf), axis=1)
        hit = np.isfinite(first)
        diameters.append(dist[np.arange(r.size), best][hit])
    diameters = np.concatenate(diameters)
    if diameters.size == 0:
        raise DatasetError("estimate_vessel_radius: no wall normal meets the opposite wall "
                           "(not a tube?)")
    return 0.5 * float(np.median(diameters))


def vessel_radius_and_source(dataset: Any, *, max_sims: int = 8) -> tuple[float, str]:
    """The vessel radius of a dataset in its length unit, and where it came from.

    Args:
        dataset: an open :class:`thrombojax.io.hdf5.Dataset` (``attrs``, ``names``,
            ``positions(name, 0)``, ``node_type(name)``, ``path``).
        max_sims: simulations the geometric estimate looks at (the first ones, natural order).
    Returns:
        ``(r, source)``; source is ``"file attribute vessel_radius"``, ``"units attribute
        'vessel radius'"`` or ``"estimated from the wall geometry of frame 0 of N
        simulation(s) (median local diameter / 2)"``.
    Raises:
        DatasetError: a ``vessel_radius`` attribute that is not a positive finite number
            (naming the file and the field), or geometry without a measurable tube.
    """
    attrs = getattr(dataset, "attrs", {})
    path = getattr(dataset, "path", "dataset")
    if "vessel_radius" in attrs:
        value = attrs["vessel_radius"]
        try:
            r = float(value)
        except (TypeError, ValueError):
            r = math.nan
        if isinstance(value, bool) or not (math.isfinite(r) and r > 0):
            raise DatasetError(f"{path}: field 'vessel_radius' (file attribute): must be a "
                               f"positive number, got {value!r}")
        return r, "file attribute vessel_radius"
    if str(attrs.get("units", "")).strip().lower() == RADIUS_UNITS:
        return 1.0, f"units attribute '{RADIUS_UNITS}'"
    names = list(dataset.names)[:max_sims]
    estimates = []
    for name in names:
        try:
            estimates.append(estimate_vessel_radius(dataset.positions(name, 0),
                                                    dataset.node_type(name)))
        except DatasetError as err:
            raise DatasetError(f"{path}: simulation '{name}': field 'positions' (frame 0): "
                               f"{err}") from err
    return float(np.median(estimates)), (
        f"estimated from the wall geometry of frame 0 of {len(names)} simulation(s) "
        "(median local diameter / 2)")


def vessel_radius(dataset: Any) -> float:
    """The vessel radius of a dataset, in the unit of its positions (module docstring).

    Args:
        dataset: an open :class:`thrombojax.io.hdf5.Dataset`.
    Returns:
        ``r`` > 0: the ``vessel_radius`` file attribute, else 1.0 when ``units`` is
        ``"vessel radius"``, else :func:`estimate_vessel_radius` (median over simulations).
    """
    return vessel_radius_and_source(dataset)[0]
