"""The rollout summary figure: surrogate, constant velocity and ground truth at a few frames.

One row per trajectory (the learned surrogate, the constant-velocity baseline, the ground truth),
one column per chosen frame, every panel with the same view box (vessel and ground truth), the
same camera and physical units. The predicted clots are coloured by their distance to the truth
on one shared colour scale, and each panel states its mean clot error, so a reader sees at a
glance where and when each prediction leaves the truth.
"""

from __future__ import annotations

import pathlib
from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from thrombojax.errors import ConfigError  # noqa: E402
from thrombojax.plotting.scene import (  # noqa: E402
    camera_angles,
    draw_clot,
    draw_wall,
    outside_box,
    save_atomic,
    setup_axes,
    view_limits,
    wall_subset,
)
from thrombojax.types import NodeType  # noqa: E402

__all__ = ["default_summary_frames", "plot_rollout_summary"]


def default_summary_frames(n_frames: int, n: int = 4) -> np.ndarray:
    """``n`` frame indices spread over ``[0, n_frames)``, first and last included, unique."""
    if n_frames < 1:
        raise ConfigError("plot_rollout_summary: no frames")
    return np.unique(np.linspace(0, n_frames - 1, min(n, n_frames)).round().astype(int))


def plot_rollout_summary(
    truth: np.ndarray,
    prediction: np.ndarray,
    constant_velocity: np.ndarray,
    node_type: np.ndarray,
    path: str | pathlib.Path,
    *,
    dt: float | None = None,
    units: str = "",
    time_unit: str = "",
    frames: Sequence[int] | None = None,
    first_frame: int = 0,
    labels: tuple[str, str, str] = ("surrogate", "constant velocity", "ground truth"),
    title: str = "",
    max_wall_points: int = 1200,
    seed: int = 0,
) -> pathlib.Path:
    """Write the summary PNG: rows surrogate / constant velocity / truth, columns frames.

    Args:
        truth, prediction, constant_velocity: ``[T, N, 3]`` positions in physical units, the
            same frames (index 0 is simulation frame ``first_frame``).
        node_type: ``[N]`` NodeType values (non-clot nodes are drawn as a faint wall subset).
        path: PNG to write.
        dt: time between frames (column titles show ``t = frame * dt``); None: frames only.
        units: length unit (axis labels, colour bar, errors). time_unit: unit of ``dt``.
        frames: indices into the arrays (default: 4 spread from the first to the last).
        first_frame: simulation frame number of index 0.
        labels: row names. title: figure title.
        max_wall_points, seed: size and seed of the drawn wall subset.
    Returns:
        The written path.
    """
    trajs = [np.asarray(a, np.float64) for a in (prediction, constant_velocity, truth)]
    if any(a.shape != trajs[2].shape for a in trajs) or trajs[2].ndim != 3 \
            or trajs[2].shape[-1] != 3:
        raise ConfigError("plot_rollout_summary: truth, prediction and constant_velocity must "
                         f"share one [T, N, 3] shape, got {[a.shape for a in trajs]}")
    n_frames = trajs[2].shape[0]
    frames = default_summary_frames(n_frames) if frames is None else np.asarray(frames, int)
    if frames.size == 0 or frames.min() < 0 or frames.max() >= n_frames:
        raise ConfigError(f"plot_rollout_summary: frames {frames.tolist()} outside [0, {n_frames})")
    clot = np.asarray(node_type) == NodeType.CLOT
    wall = wall_subset(node_type, max_wall_points, seed)
    lim = view_limits(trajs[2], node_type)
    angles = camera_angles(trajs[2][0, wall] if wall.size else trajs[2][0])
    units = units or "length unit"
    errors = [np.linalg.norm(a[:, clot] - trajs[2][:, clot], axis=-1) for a in trajs[:2]]
    shown = np.concatenate([e[frames].ravel() for e in errors])
    shown = shown[np.isfinite(shown)]
    top = float(np.percentile(shown, 99)) if shown.size else 1.0
    norm = plt.Normalize(0.0, max(min(top, (lim[0, 1] - lim[0, 0]) / 5), 1e-12))
    n_cols = frames.size
    fig = plt.figure(figsize=(3.3 * n_cols + 0.9, 10.8), dpi=100)
    mappable, first_column = None, []
    for row, traj in enumerate(trajs):
        for col, t in enumerate(frames):
            ax = fig.add_subplot(3, n_cols, row * n_cols + col + 1, projection="3d")
            if col == 0:
                first_column.append(ax)
            setup_axes(ax, lim, None, angles)
            draw_wall(ax, trajs[2][0, wall])
            if row < 2:
                mappable = draw_clot(ax, traj[t, clot], values=errors[row][t], norm=norm,
                                     cmap="plasma", size=5.0)
                n_out = int(outside_box(traj[t, clot], lim).sum())
                note = f"mean error {np.nanmean(errors[row][t]):.3g} {units}"
                note += f"\n{n_out} nodes outside the view" if n_out else ""
            else:
                draw_clot(ax, traj[t, clot], color="tab:blue", size=5.0)
                note = ""
            frame = first_frame + int(t)
            when = f"frame {frame}" + (f", t = {frame * dt:.3g} {time_unit}".rstrip()
                                       if dt is not None else "")
            ax.set_title(f"{when}\n{note}" if row == 0 else note, fontsize=8.5)
    fig.subplots_adjust(left=0.05, right=0.9, bottom=0.03, top=0.89, wspace=0.08, hspace=0.18)
    for ax, label in zip(first_column, labels, strict=True):  # in the margin, clear of the z axis
        box = ax.get_position()
        fig.text(0.012, (box.y0 + box.y1) / 2, label, rotation=90, va="center", ha="center",
                 fontsize=11, fontweight="bold")
    bar_ax = fig.add_axes((0.92, 0.4, 0.015, 0.45))
    bar = fig.colorbar(mappable, cax=bar_ax, extend="max")
    bar.set_label(f"clot error: distance to truth [{units}]", fontsize=9)
    head = title or "rollout: surrogate vs constant velocity vs ground truth"
    fig.suptitle(f"{head}\n(lengths in {units})", fontsize=12)
    try:
        return save_atomic(lambda tmp: fig.savefig(tmp, format="png"), path)
    finally:
        plt.close(fig)
