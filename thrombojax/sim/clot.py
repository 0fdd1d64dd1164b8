"""The clot: a cylinder of linear tetrahedra without slivers, and its placement in the vessel.

Mesh: a structured hex grid over the square ``[-1, 1]^2`` times the length, 6 tetrahedra per
hex (Kuhn split along the hex diagonal), with the split mirrored per quadrant of the square so
that the split diagonals point away from the axis everywhere (the rim gets no flat tets), then
the square mapped onto the disc with the concentric (Shirley-Chiu) map, which keeps the rings
of cells concentric (the naive radial map squashes the cells on the diagonals into slivers).
Mirrored Kuhn splits stay conforming: two hexes sharing a face split it along the same diagonal,
because the mirror flips only the axis normal to the mirror plane.
"""

from __future__ import annotations

import itertools

import numpy as np

from thrombojax.errors import ConfigError
from thrombojax.sim.geometry import Centreline, transport_frames

__all__ = [
    "cylinder_mesh",
    "square_to_disc",
    "tet_volumes",
    "tet_min_heights",
    "surface_triangles",
    "nodal_areas",
    "lumped_masses",
    "place_clot",
]


def square_to_disc(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Concentric map of the square ``[-1, 1]^2`` onto the unit disc (Shirley & Chiu 1997)."""
    u, v = np.asarray(u, np.float64), np.asarray(v, np.float64)
    x, y = np.zeros_like(u), np.zeros_like(v)
    a = (np.abs(u) >= np.abs(v)) & (u != 0)
    b = ~a & (v != 0)
    phi = np.pi / 4 * v[a] / u[a]
    x[a], y[a] = u[a] * np.cos(phi), u[a] * np.sin(phi)
    phi = np.pi / 2 - np.pi / 4 * u[b] / v[b]
    x[b], y[b] = v[b] * np.cos(phi), v[b] * np.sin(phi)
    return x, y


def cylinder_mesh(
    n_cross: int, n_len: int, radius: float, length: float
) -> tuple[np.ndarray, np.ndarray]:
    """Tetrahedral mesh of a straight cylinder along +z, from ``z = 0`` to ``z = length``.

    Args:
        n_cross: hex cells across the diameter (even, >= 2).
        n_len: hex cells along the length.
        radius, length: size of the cylinder.

    Returns:
        ``(nodes [(n_cross+1)^2 (n_len+1), 3] float64, tets [6 n_cross^2 n_len, 4] int32)``,
        every tet positively oriented.
    """
    if n_cross < 2 or n_cross % 2 or n_len < 1:
        raise ConfigError(
            f"clot mesh needs an even n_cross >= 2 and n_len >= 1, got {n_cross}, {n_len}"
        )
    n = n_cross
    g = np.linspace(-1.0, 1.0, n + 1)
    uu, vv, zz = np.meshgrid(g, g, np.linspace(0.0, length, n_len + 1), indexing="ij")
    x, y = square_to_disc(uu.ravel(), vv.ravel())
    nodes = np.stack([radius * x, radius * y, zz.ravel()], 1)
    idx = np.arange(nodes.shape[0]).reshape(n + 1, n + 1, n_len + 1)
    square = np.stack([uu.ravel(), vv.ravel(), zz.ravel()], 1)

    i, j, k = (
        a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), np.arange(n_len), indexing="ij")
    )
    flip_i = i < n // 2
    flip_j = j < n // 2
    tets = []
    for perm in itertools.permutations(range(3)):
        path = [np.zeros(3, int)]
        for ax in perm:
            step = path[-1].copy()
            step[ax] = 1
            path.append(step)
        corners = []
        for bits in path:
            a = np.where(flip_i, 1 - bits[0], bits[0])
            b = np.where(flip_j, 1 - bits[1], bits[1])
            corners.append(idx[i + a, j + b, k + bits[2]])
        tets.append(np.stack(corners, 1))
    tets = np.concatenate(tets).astype(np.int32)
    # orient on the (undistorted) square grid, where every Kuhn tet has volume h^3/6
    e = square[tets[:, 1:]] - square[tets[:, :1]]
    neg = np.linalg.det(e) < 0
    tets[neg, 1], tets[neg, 2] = tets[neg, 2].copy(), tets[neg, 1].copy()
    if np.any(tet_volumes(nodes, tets) <= 0):
        raise ConfigError("clot mesh has inverted tetrahedra")
    return nodes, tets


def tet_volumes(x: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes ``[C]`` of tetrahedra ``tets [C, 4]`` at positions ``x [N, 3]``."""
    e = x[tets[:, 1:]] - x[tets[:, :1]]
    return np.linalg.det(e) / 6.0


def tet_min_heights(x: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Smallest height ``[C]`` of each tetrahedron (3 volume / largest face area)."""
    vol = np.abs(tet_volumes(x, tets))
    faces = ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))
    areas = []
    for f in faces:
        p = x[tets[:, f]]
        areas.append(0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1))
    return 3.0 * vol / np.max(areas, axis=0)


def surface_triangles(tets: np.ndarray) -> np.ndarray:
    """Boundary faces ``[B, 3]`` of a tet mesh (faces that belong to exactly one tet)."""
    faces = np.concatenate(
        [tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]]
    )
    key = np.sort(faces, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[counts[inv.ravel()] == 1]


def nodal_areas(x: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Boundary area lumped to nodes ``[N]`` (a third of each boundary triangle; 0 inside)."""
    tri = surface_triangles(tets)
    p = x[tri]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    out = np.zeros(len(x))
    np.add.at(out, tri.ravel(), np.repeat(area / 3.0, 3))
    return out


def lumped_masses(x: np.ndarray, tets: np.ndarray, density: float = 1.0) -> np.ndarray:
    """Row-sum lumped masses ``[N]``: a quarter of each tet's mass to each of its nodes."""
    out = np.zeros(len(x))
    np.add.at(out, tets.ravel(), np.repeat(density * tet_volumes(x, tets) / 4.0, 4))
    return out


def place_clot(
    rest: np.ndarray,
    cl: Centreline,
    s_back: float,
    rest_radius: float,
    length_in_vessel: float,
    roll_deg: float,
    squeeze: float,
) -> np.ndarray:
    """Bend a straight rest cylinder onto the centreline and squeeze it inside the wall.

    A rest node at radius ``rho``, angle ``theta`` and height ``z`` goes to arc length
    ``s_back + z * length_in_vessel / rest_length`` at radius ``squeeze * r(s) * rho /
    rest_radius`` and angle ``theta + roll`` in the centreline's rotation-minimising frame.

    Args:
        rest: ``[N, 3]`` rest nodes (cylinder along +z from 0).
        cl: the centreline.
        s_back: arc length of the clot's back end.
        rest_radius: radius of the rest cylinder.
        length_in_vessel: length of the placed clot along the centreline.
        roll_deg: rotation of the mesh about its axis.
        squeeze: placed radius as a fraction of the local vessel radius (< 1: no contact yet).

    Returns:
        ``[N, 3]`` placed positions.
    """
    arc, pts = np.asarray(cl.arc), np.asarray(cl.points)
    s = s_back + rest[:, 2] * length_in_vessel / rest[:, 2].max()
    if s.min() < 0 or s.max() > arc[-1]:
        raise ConfigError(
            f"clot [{s.min():.2f}, {s.max():.2f}] does not fit in the vessel [0, {arc[-1]:.2f}]"
        )
    _, n1, n2 = transport_frames(pts)
    interp = lambda a: np.stack([np.interp(s, arc, a[:, k]) for k in range(3)], 1)  # noqa: E731
    centre, f1 = interp(pts), interp(n1)
    t = interp(np.gradient(pts, arc, axis=0))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    f1 -= np.sum(f1 * t, axis=1, keepdims=True) * t
    f1 /= np.linalg.norm(f1, axis=1, keepdims=True)
    f2 = np.cross(t, f1)
    roll = np.deg2rad(roll_deg)
    c, sn = np.cos(roll), np.sin(roll)
    px = c * rest[:, 0] - sn * rest[:, 1]
    py = sn * rest[:, 0] + c * rest[:, 1]
    scale = squeeze * np.interp(s, arc, np.asarray(cl.radius)) / rest_radius
    return centre + scale[:, None] * (px[:, None] * f1 + py[:, None] * f2)
