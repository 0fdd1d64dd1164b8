"""Shared pieces of the 3-D pictures: the view box, the camera, the wall subset, the scene.

A picture of a clot in a vessel must stay readable when a prediction goes wrong, so the view
box comes from what is known to be right, the vessel wall and the ground-truth clot, never from
the prediction (a diverging prediction leaves the box and is clipped, with a count of the nodes
outside written on the panel). The three axes share one scale, the clot is drawn above the wall
whatever the camera, and the camera looks at the vessel across its flattest direction, so a bend
is seen as a bend.
"""

from __future__ import annotations

import pathlib
from collections.abc import Callable

import numpy as np

from thrombojax.io.outputs import atomic_path
from thrombojax.types import NodeType

__all__ = [
    "view_limits", "camera_angles", "wall_subset", "outside_box", "setup_axes", "draw_wall",
    "draw_clot", "save_atomic", "WALL_STYLE",
]

WALL_STYLE = {"s": 3.0, "c": "0.5", "alpha": 0.35, "depthshade": False, "linewidths": 0}


def view_limits(true: np.ndarray, node_type: np.ndarray, pad: float = 0.06) -> np.ndarray:
    """The view box: one cube containing the vessel wall and the ground-truth clot, all frames.

    Args:
        true: ``[T, N, 3]`` (or ``[N, 3]``) ground-truth positions.
        node_type: ``[N]`` NodeType values.
        pad: margin, as a fraction of the half side.
    Returns:
        ``[3, 2]`` (min, max) per axis, the same side on every axis.
    """
    true = np.asarray(true, np.float64)
    true = true[None] if true.ndim == 2 else true
    clot = np.asarray(node_type) == NodeType.CLOT
    pts = np.concatenate([true[0, ~clot], true[:, clot].reshape(-1, 3)])
    pts = pts[np.isfinite(pts).all(axis=1)]
    if not len(pts):
        return np.tile([-1.0, 1.0], (3, 1))
    lo, hi = pts.min(0), pts.max(0)
    centre, half = (lo + hi) / 2, max((hi - lo).max() / 2, 1e-9) * (1 + pad)
    return np.stack([centre - half, centre + half], axis=1)


def camera_angles(points: np.ndarray, tilt: float = 30.0) -> tuple[float, float]:
    """Elevation and azimuth (degrees): across the points' flattest direction, tilted.

    The direction of least variance is the normal of the plane a bent tube lies in; looking
    along it shows the bend. The camera is then tilted by ``tilt`` degrees about the points'
    longest direction (which stays horizontal on the screen), so the picture stays 3-D.
    """
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) < 3:
        return 20.0, -60.0
    _, vecs = np.linalg.eigh(np.cov((pts - pts.mean(0)).T))
    normal, longest = vecs[:, 0], vecs[:, 2]
    side = np.cross(longest, normal)  # in the plane, across the longest direction
    view = np.cos(np.radians(tilt)) * normal + np.sin(np.radians(tilt)) * side
    view = view if view[2] >= 0 else -view
    elev = float(np.degrees(np.arcsin(np.clip(view[2], -1.0, 1.0))))
    if np.hypot(view[0], view[1]) < 1e-6:
        return elev, float(np.degrees(np.arctan2(longest[1], longest[0])) - 90.0)
    return elev, float(np.degrees(np.arctan2(view[1], view[0])))


def wall_subset(node_type: np.ndarray, max_points: int, seed: int = 0) -> np.ndarray:
    """Indices of at most ``max_points`` non-clot nodes (a fixed seeded subset, sorted)."""
    wall = np.flatnonzero(np.asarray(node_type) != NodeType.CLOT)
    if wall.size > max_points:
        wall = np.sort(np.random.default_rng(seed).choice(wall, max_points, replace=False))
    return wall


def outside_box(points: np.ndarray, lim: np.ndarray) -> np.ndarray:
    """``[n]`` bool: the point is outside the view box (or not finite)."""
    pts = np.asarray(points, np.float64)
    inside = (pts >= lim[:, 0]) & (pts <= lim[:, 1])
    return ~inside.all(axis=-1)


def setup_axes(ax, lim: np.ndarray, units: str | None, angles: tuple[float, float]) -> None:
    """Limits, equal aspect, axis labels (``x [units]``, or bare with ``units=None``), few ticks,
    light panes, the camera and the clot-on-top drawing order."""
    from matplotlib.ticker import MaxNLocator

    ax.computed_zorder = False  # draw in call order: the clot over the wall, whatever the view
    ax.set(xlim=lim[0], ylim=lim[1], zlim=lim[2])
    ax.set_box_aspect((1, 1, 1))
    for axis, label in zip((ax.xaxis, ax.yaxis, ax.zaxis), "xyz", strict=True):
        axis.set_major_locator(MaxNLocator(4))
        axis.set_label_text(label if units is None else f"{label} [{units}]", fontsize=8)
        axis.set_tick_params(labelsize=7, pad=0)
        axis.labelpad = 2
        axis.set_pane_color((0.97, 0.97, 0.97, 1.0))
    ax.view_init(elev=angles[0], azim=angles[1])


def draw_wall(ax, wall_xyz: np.ndarray, label: str = "vessel wall"):
    """Faint grey wall points, below everything else (larger and darker when they are few)."""
    xyz = np.asarray(wall_xyz).reshape(-1, 3)
    style = dict(WALL_STYLE)
    if len(xyz) < 1000:  # a coarse wall: make each point count
        style |= {"s": 6.0, "alpha": 0.5}
    return ax.scatter(*xyz.T, zorder=1, label=label, axlim_clip=True, **style)


def draw_clot(ax, clot_xyz: np.ndarray, *, values=None, color="tab:blue", cmap="plasma",
              norm=None, size: float = 6.0, label: str = "clot", zorder: int = 2):
    """Clot nodes above the wall, a solid colour or coloured by ``values`` (``cmap``, ``norm``)."""
    xyz = np.asarray(clot_xyz).T
    if values is None:
        return ax.scatter(*xyz, s=size, c=color, depthshade=False, zorder=zorder, label=label,
                          linewidths=0, axlim_clip=True)
    return ax.scatter(*xyz, s=size, c=np.asarray(values), cmap=cmap, norm=norm,
                      depthshade=False, zorder=zorder, label=label, linewidths=0,
                      axlim_clip=True)


def save_atomic(write: Callable[[pathlib.Path], object], path: str | pathlib.Path) -> pathlib.Path:
    """Write a picture atomically: ``write(tmp)`` into a tagged temporary beside ``path``, then
    rename (:func:`thrombojax.io.outputs.atomic_path`: the temporary keeps the suffix, a killed
    write leaves a temporary that the next write in that folder removes).
    """
    path = pathlib.Path(path)
    with atomic_path(path) as tmp:
        write(tmp)
    return path
