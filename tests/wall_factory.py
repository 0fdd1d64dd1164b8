"""A small bent vessel (wall triangles, centreline) with a clot inside, for the guard tests."""

from __future__ import annotations

import numpy as np

from thrombojax.sim.geometry import bent_tube_points, make_centreline, signed_distance_np, wall_mesh

N_CLOT = 60


def bent_vessel(seed: int = 0, n_rings: int = 14, n_around: int = 12):
    """A 90-degree bent tube of radius 1 (open at both ends) and a blob of clot nodes inside.

    Returns:
        dict with ``positions [N, 3]`` (clot first, then wall nodes), ``node_type [N]``,
        ``wall_cells [F, 3]`` (global indices), ``centreline`` and ``clot`` (``[N] bool``).
    """
    rng = np.random.default_rng(seed)
    pts = bent_tube_points(2.0, 2.0, 2.5, 90.0, 0.1)
    cl = make_centreline(pts, np.ones(len(pts)))
    wall, tris = wall_mesh(cl, n_rings, n_around)
    # clot: points within 0.7 of centreline points in the bend
    centre = pts[rng.integers(len(pts) // 4, 3 * len(pts) // 4, N_CLOT)]
    offset = rng.normal(size=(N_CLOT, 3))
    offset *= (0.7 * rng.uniform(0, 1, (N_CLOT, 1)) ** (1 / 3)) / np.linalg.norm(
        offset, axis=1, keepdims=True)
    clot = centre + offset
    positions = np.concatenate([clot, wall])
    node_type = np.array([1] * N_CLOT + [0] * len(wall), np.int8)
    return {
        "positions": positions,
        "node_type": node_type,
        "wall_cells": tris + N_CLOT,
        "centreline": cl,
        "clot": node_type == 1,
    }


def radial_push(vessel: dict, amount: float) -> np.ndarray:
    """Positions after a model-like step that pushes every clot node outward by ``amount``.

    The push is along the node's radial direction from the centreline; wall nodes stay.
    """
    x = vessel["positions"].copy()
    clot = vessel["clot"]
    sd = signed_distance_np(vessel["centreline"], x[clot])
    cl = vessel["centreline"]
    p0, tan = np.asarray(cl.points)[sd["seg"]], np.asarray(cl.tangent)[sd["seg"]]
    rel = x[clot] - p0
    radial = rel - np.sum(rel * tan, axis=1, keepdims=True) * tan
    radial /= np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-9)
    x[clot] += amount * radial
    return x


def true_phi(vessel: dict, x: np.ndarray) -> np.ndarray:
    """Signed distance to the smooth vessel wall (> 0 inside) of the clot nodes of ``x``."""
    return signed_distance_np(vessel["centreline"], x[vessel["clot"]])["phi"]
