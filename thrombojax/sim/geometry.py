"""Rigid vessels: a tube of radius ``r(s)`` around a smooth centreline.

The vessel is represented by its centreline, a polyline of ``S`` points sampled finely
(spacing ~0.2 radius, chord error < 0.3 % of the radius at the smallest bend radius), and a
radius per point, linearly interpolated along each segment. The signed distance to the wall
is ``phi = r(s) - |x - c(x)|`` (positive inside), with ``c(x)`` the nearest centreline point;
its gradient (the radial direction) is used as the wall normal. Where the radius varies slowly
(``|dr/ds| << 1``, as here) this is the true wall distance to first order; vessels segmented from
images would need a signed-distance grid instead (``SOLVER.md``).

Nodes past either end of the centreline are "outside": they get no contact, so a clot can
leave the vessel and relax. Each node remembers its nearest segment and the jitted search
(:func:`nearest_segment`) looks only at a few segments around it per substep; the numpy
brute-force search (:func:`signed_distance_np`) is its reference and starts the tracking.

The wall itself, for the dataset, is rings of points around the centreline (rotation-minimising
frames, so the rings do not twist) joined by triangles.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import struct

from thrombojax.errors import ConfigError

__all__ = [
    "Centreline",
    "make_centreline",
    "resample_polyline",
    "bent_tube_points",
    "tortuous_points",
    "radius_profile",
    "transport_frames",
    "wall_mesh",
    "signed_distance_np",
    "nearest_segment",
    "rotation_matrix",
]


@struct.dataclass
class Centreline:
    """A vessel centreline with its radius (a pytree of arrays).

    Attributes:
        points: ``[S, 3]`` centreline points.
        radius: ``[S]`` vessel radius at each point.
        tangent: ``[S-1, 3]`` unit direction of each segment.
        seg_len: ``[S-1]`` segment lengths.
        arc: ``[S]`` arc length at each point (``arc[0] = 0``).
    """

    points: jnp.ndarray
    radius: jnp.ndarray
    tangent: jnp.ndarray
    seg_len: jnp.ndarray
    arc: jnp.ndarray

    @property
    def length(self) -> float:
        """Total arc length."""
        return float(self.arc[-1])


def make_centreline(points: np.ndarray, radius: np.ndarray) -> Centreline:
    """Build a :class:`Centreline` (numpy arrays) from points ``[S, 3]`` and radii ``[S]``."""
    points = np.asarray(points, dtype=np.float64)
    radius = np.asarray(radius, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] < 2:
        raise ConfigError(f"centreline points must be [S>=2, 3], got {points.shape}")
    if radius.shape != points.shape[:1] or np.any(radius <= 0):
        raise ConfigError("centreline radius must be [S] and positive")
    edges = np.diff(points, axis=0)
    seg_len = np.linalg.norm(edges, axis=1)
    if np.any(seg_len <= 0):
        raise ConfigError("centreline has repeated points")
    arc = np.concatenate([[0.0], np.cumsum(seg_len)])
    return Centreline(points, radius, edges / seg_len[:, None], seg_len, arc)


def resample_polyline(points: np.ndarray, n: int) -> np.ndarray:
    """Resample a polyline ``[S, 3]`` to ``n`` points equally spaced in arc length."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.linspace(0.0, arc[-1], n)
    return np.stack([np.interp(s, arc, points[:, k]) for k in range(3)], axis=1)


def bent_tube_points(
    leg_in: float, leg_out: float, bend_radius: float, bend_angle_deg: float, spacing: float
) -> np.ndarray:
    """Centreline of a straight leg, a circular bend and a second straight leg.

    The inlet leg runs along +x from the origin; the bend turns towards +y in the x-y plane.

    Args:
        leg_in, leg_out: lengths of the straight legs.
        bend_radius: centreline radius of the bend.
        bend_angle_deg: turning angle of the bend.
        spacing: target distance between centreline points.

    Returns:
        ``[S, 3]`` points, equally spaced in arc length.
    """
    ang = np.deg2rad(bend_angle_deg)
    s_in = np.linspace(0.0, leg_in, 200)
    p_in = np.stack([s_in, 0 * s_in, 0 * s_in], 1)
    th = np.linspace(0.0, ang, 200)
    p_bend = np.stack(
        [leg_in + bend_radius * np.sin(th), bend_radius * (1 - np.cos(th)), 0 * th], 1
    )
    direction = np.array([np.cos(ang), np.sin(ang), 0.0])
    s_out = np.linspace(0.0, leg_out, 200)
    p_out = p_bend[-1] + s_out[:, None] * direction
    dense = np.concatenate([p_in, p_bend[1:], p_out[1:]])
    total = leg_in + bend_radius * ang + leg_out
    return resample_polyline(dense, int(round(total / spacing)) + 1)


def tortuous_points(
    rng: np.random.Generator,
    length: float,
    min_bend_radius: float,
    spacing: float,
    clearance: float,
    *,
    max_tries: int = 200,
) -> np.ndarray:
    """A random smooth space curve with bounded curvature that never approaches itself.

    The curvature vector (in a parallel-transported frame) is a sum of four random Fourier
    modes of wavelengths 6-30, scaled so that ``|kappa| <= 1 / min_bend_radius``. Curves where
    two points more than ``3 * clearance`` apart along the curve come closer than ``clearance``
    are rejected and redrawn.

    Args:
        rng: numpy generator (the vessel's seed).
        length: arc length of the curve.
        min_bend_radius: smallest radius of curvature.
        spacing: distance between output points.
        clearance: smallest allowed distance between far-apart parts of the curve.
        max_tries: draws before giving up.

    Returns:
        ``[S, 3]`` points, ``S = round(length / spacing) + 1``.
    """
    n = int(round(length / spacing)) + 1
    s = np.linspace(0.0, length, n)
    ds = s[1] - s[0]
    for _ in range(max_tries):
        kap = np.zeros((n, 2))
        for _m in range(4):
            wave = rng.uniform(6.0, 30.0)
            phase = rng.uniform(0, 2 * np.pi, 2)
            amp = rng.normal(size=2)
            kap += amp * np.sin(2 * np.pi * s[:, None] / wave + phase)
        kap *= rng.uniform(0.6, 1.0) / (min_bend_radius * np.linalg.norm(kap, axis=1).max())
        t, n1 = np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
        pts = np.zeros((n, 3))
        for i in range(1, n):
            n2 = np.cross(t, n1)
            t_new = t + ds * (kap[i - 1, 0] * n1 + kap[i - 1, 1] * n2)
            t_new /= np.linalg.norm(t_new)
            pts[i] = pts[i - 1] + ds * 0.5 * (t + t_new)
            n1 = n1 - np.dot(n1, t_new) * t_new
            n1 /= np.linalg.norm(n1)
            t = t_new
        dist = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
        far = np.abs(s[:, None] - s[None]) > 3.0 * clearance
        if not np.any(far & (dist < clearance)):
            return pts
    raise ConfigError(f"no self-avoiding tortuous centreline found in {max_tries} draws")


def radius_profile(
    arc: np.ndarray, r_start: float, r_end: float, wobble: float, rng: np.random.Generator | None
) -> np.ndarray:
    """Radius along the vessel: a linear taper ``r_start -> r_end`` times ``1 +- wobble``.

    The wobble is two random sinusoids (wavelengths 8-20) normalised to amplitude ``wobble``,
    faded in over the first 5 % of the length so the inlet radius is exactly ``r_start``.
    """
    u = arc / arc[-1]
    r = r_start + (r_end - r_start) * u
    if rng is None or wobble == 0.0:
        return r
    w = np.zeros_like(arc)
    for _ in range(2):
        w += np.sin(2 * np.pi * arc / rng.uniform(8.0, 20.0) + rng.uniform(0, 2 * np.pi))
    w *= wobble / max(np.abs(w).max(), 1e-12) * np.clip(u / 0.05, 0.0, 1.0)
    return r * (1.0 + w)


def transport_frames(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rotation-minimising frames along a polyline (parallel transport, no twist).

    Returns:
        ``(t, n1, n2)``, each ``[S, 3]``: unit tangents and two unit normals per point.
    """
    edges = np.diff(points, axis=0)
    edges /= np.linalg.norm(edges, axis=1, keepdims=True)
    t = np.concatenate([edges[:1], edges[:-1] + edges[1:], edges[-1:]])
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    trial = np.eye(3)[np.argmin(np.abs(t[0]))]
    n1 = np.zeros_like(t)
    n1[0] = trial - np.dot(trial, t[0]) * t[0]
    n1[0] /= np.linalg.norm(n1[0])
    for i in range(1, len(t)):
        v = n1[i - 1] - np.dot(n1[i - 1], t[i]) * t[i]
        n1[i] = v / np.linalg.norm(v)
    return t, n1, np.cross(t, n1)


def wall_mesh(cl: Centreline, n_rings: int, n_around: int) -> tuple[np.ndarray, np.ndarray]:
    """Wall points as rings around the centreline, joined by triangles.

    Args:
        cl: the centreline.
        n_rings: rings, equally spaced in arc length from end to end.
        n_around: points per ring.

    Returns:
        ``(points [n_rings * n_around, 3] float64, triangles [2 * (n_rings-1) * n_around, 3]
        int32)``; ring ``i`` holds points ``i * n_around ... (i+1) * n_around - 1``.
    """
    arc = np.asarray(cl.arc)
    s = np.linspace(0.0, arc[-1], n_rings)
    pts = np.asarray(cl.points)
    centre = np.stack([np.interp(s, arc, pts[:, k]) for k in range(3)], 1)
    rad = np.interp(s, arc, np.asarray(cl.radius))
    _, n1, n2 = transport_frames(pts)
    f1 = np.stack([np.interp(s, arc, n1[:, k]) for k in range(3)], 1)
    t = np.stack([np.interp(s, arc, np.gradient(pts[:, k], arc)) for k in range(3)], 1)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    f1 -= np.sum(f1 * t, axis=1, keepdims=True) * t
    f1 /= np.linalg.norm(f1, axis=1, keepdims=True)
    f2 = np.cross(t, f1)
    th = 2 * np.pi * np.arange(n_around) / n_around
    ring = np.cos(th)[None, :, None] * f1[:, None] + np.sin(th)[None, :, None] * f2[:, None]
    points = centre[:, None] + rad[:, None, None] * ring
    i, j = np.meshgrid(np.arange(n_rings - 1), np.arange(n_around), indexing="ij")
    a = i * n_around + j
    b = i * n_around + (j + 1) % n_around
    c, d = a + n_around, b + n_around
    tris = np.concatenate([np.stack([a, b, d], -1), np.stack([a, d, c], -1)], 1)
    return points.reshape(-1, 3), tris.reshape(-1, 3).astype(np.int32)


def _project(points, tangent, seg_len, seg, x):
    """Project ``x [..., 3]`` onto segments ``seg [...]``; returns (unclamped t, closest, dist)."""
    p0 = points[seg]
    d = tangent[seg]
    t_raw = jnp.sum((x - p0) * d, axis=-1)
    t = jnp.clip(t_raw, 0.0, seg_len[seg])
    c = p0 + t[..., None] * d
    dist = jnp.linalg.norm(x - c, axis=-1)
    return t_raw, t, c, dist


def signed_distance_np(cl: Centreline, x: np.ndarray) -> dict[str, np.ndarray]:
    """Brute-force signed distance of points to the wall (numpy reference; all segments).

    Args:
        cl: the centreline.
        x: ``[N, 3]`` points.

    Returns:
        dict with ``phi [N]`` (radius minus distance; > 0 inside), ``seg [N]`` nearest segment,
        ``radius [N]`` local radius, ``outside [N]`` bool (past either end of the centreline),
        ``beyond [N]`` distance past the outlet plane along the last tangent.
    """
    pts, tan, sl = (np.asarray(a, np.float64) for a in (cl.points, cl.tangent, cl.seg_len))
    x = np.asarray(x, np.float64)
    rel = x[:, None] - pts[None, :-1]
    t_raw = np.einsum("nsk,sk->ns", rel, tan)
    t = np.clip(t_raw, 0.0, sl[None])
    dist = np.linalg.norm(rel - t[..., None] * tan[None], axis=-1)
    seg = np.argmin(dist, axis=1)
    rows = np.arange(len(x))
    frac = t[rows, seg] / sl[seg]
    r = np.asarray(cl.radius)
    radius = r[seg] * (1 - frac) + r[seg + 1] * frac
    last = len(sl) - 1
    tr = t_raw[rows, seg]
    outside = ((seg == last) & (tr > sl[last])) | ((seg == 0) & (tr < 0))
    beyond = np.where(seg == last, tr - sl[last], -np.inf)
    return {
        "phi": radius - dist[rows, seg],
        "seg": seg,
        "radius": radius,
        "outside": outside,
        "beyond": beyond,
    }


def nearest_segment(cl: Centreline, x: jnp.ndarray, seg: jnp.ndarray, window: int = 2):
    """Nearest centreline segment of each point, searched near its previous one (jittable).

    Args:
        cl: the centreline (arrays may be jax arrays).
        x: ``[N, 3]`` points.
        seg: ``[N]`` int32 previous nearest segment.
        window: segments searched on each side of ``seg``.

    Returns:
        dict with ``seg [N]``, ``phi [N]`` (> 0 inside), ``normal [N, 3]`` (outward, unit),
        ``tangent [N, 3]`` (segment direction), ``inside [N]`` bool (not past either end),
        ``beyond [N]`` distance past the outlet end (-inf when not on the last segment).
    """
    n_seg = cl.seg_len.shape[0]
    offs = jnp.arange(-window, window + 1, dtype=seg.dtype)
    cand = jnp.clip(seg[:, None] + offs[None], 0, n_seg - 1)  # [N, W]
    t_raw, t, c, dist = _project(cl.points, cl.tangent, cl.seg_len, cand, x[:, None])
    k = jnp.argmin(dist, axis=1)
    take = lambda a: jnp.take_along_axis(a, k[:, None], axis=1)[:, 0]  # noqa: E731
    new = take(cand)
    t_raw, t, dist = take(t_raw), take(t), take(dist)
    c = jnp.take_along_axis(c, k[:, None, None], axis=1)[:, 0]
    frac = t / cl.seg_len[new]
    radius = cl.radius[new] * (1 - frac) + cl.radius[new + 1] * frac
    normal = (x - c) / jnp.maximum(dist, 1e-12)[:, None]
    last = n_seg - 1
    outside = ((new == last) & (t_raw > cl.seg_len[last])) | ((new == 0) & (t_raw < 0))
    beyond = jnp.where(new == last, t_raw - cl.seg_len[last], -jnp.inf)
    return {
        "seg": new,
        "phi": radius - dist,
        "normal": normal,
        "tangent": cl.tangent[new],
        "inside": ~outside,
        "beyond": beyond,
        "radius": radius,
    }


def rotation_matrix(axis: str, angle_deg: float) -> np.ndarray:
    """``[3, 3]`` rotation by ``angle_deg`` about the coordinate axis ``"x"``, ``"y"``, ``"z"``."""
    a = np.deg2rad(angle_deg)
    c, s = np.cos(a), np.sin(a)
    i = "xyz".index(axis)
    j, k = (i + 1) % 3, (i + 2) % 3
    m = np.eye(3)
    m[j, j], m[j, k], m[k, j], m[k, k] = c, -s, s, c
    return m
