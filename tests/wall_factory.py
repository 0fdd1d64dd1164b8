"""A small bent vessel (wall triangles, centreline) with a clot inside, for the guard tests."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
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


def straight_tube(half_length: float = 2.0, n_rings: int = 21, n_clot: int = 30, seed: int = 0):
    """``(x0 [N, 3] float32, node_type [N])``: a unit-radius tube along x (rings of 24 vessel
    nodes from ``-half_length`` to ``half_length``) with ``n_clot`` clot nodes first, uniform in
    ``[-0.8, 0.8] x [-0.4, 0.4]^2``."""
    from thrombojax.types import NodeType

    ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    ring = np.stack([np.zeros_like(ang), np.cos(ang), np.sin(ang)], 1)
    wall = np.concatenate([ring + [x, 0, 0]
                           for x in np.linspace(-half_length, half_length, n_rings)])
    clot = np.random.default_rng(seed).uniform(-0.4, 0.4, (n_clot, 3)) * [2.0, 1.0, 1.0]
    x0 = np.concatenate([clot, wall]).astype(np.float32)
    node_type = np.array([NodeType.CLOT] * n_clot + [NodeType.VESSEL] * len(wall), np.int32)
    return x0, node_type


@dataclasses.dataclass(frozen=True)
class Outward:
    """A surrogate that accelerates every node away from the x axis of its inputs (the axis of
    :func:`straight_tube`), 0.05 per step: its clot leaves the tube unless guarded."""

    name: str = "outward"

    def build_graph(self, inputs):
        return {}

    def init(self, rng, inputs, graph):
        return {}

    def apply(self, params, inputs, graph, *, train=False, rng=None):
        radial = inputs.positions * jnp.asarray([0.0, 1.0, 1.0])
        return 0.05 * radial / (jnp.linalg.norm(radial, axis=-1, keepdims=True) + 1e-6)


def clot_cloud(n_real: int = 40, n_pad: int = 5, seed: int = 0):
    """``(ref [N, 3] float32, mask [N])``: an elongated cloud of ``n_real`` clot nodes (std 1,
    0.4, 0.3 along x, y, z) and ``n_pad`` padded rows at 7.0, for the coherence guard's tests."""
    rng = np.random.default_rng(seed)
    ref = np.concatenate([rng.normal(size=(n_real, 3)) * [1.0, 0.4, 0.3],
                          np.full((n_pad, 3), 7.0)]).astype(np.float32)
    return ref, np.arange(n_real + n_pad) < n_real
