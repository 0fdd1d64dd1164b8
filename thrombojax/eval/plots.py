"""Matplotlib figures: rollout error curves and prediction-beside-truth animations.

Every function takes plain numpy arrays, writes one file and returns its path; none keeps
state. 3-D views use equal axis scaling (one cube of limits shared by both panels, box
aspect 1:1:1), so shapes are not distorted and the two panels compare directly.
"""

from __future__ import annotations

import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from thrombojax.types import NodeType  # noqa: E402

__all__ = ["plot_error_curves", "plot_rollout_metrics", "equal_limits", "animate_rollout"]

_BASELINE_STYLE = {"linestyle": "--", "color": "0.4"}


def plot_error_curves(
    curves: dict[str, np.ndarray],
    path: str | pathlib.Path,
    *,
    ylabel: str = "MSE (clot nodes, scaled coords)",
    title: str = "Rollout error per step",
    logy: bool = True,
    start: int = 1,
) -> pathlib.Path:
    """Line plot of one or more per-step curves (e.g. model vs constant-velocity baseline).

    Args:
        curves: label -> ``[n_steps]`` values; labels containing "constant" are dashed grey.
        path: PNG to write.
        ylabel, title: axis label and title. logy: logarithmic y axis.
        start: the step number of the first value (x axis).
    Returns:
        The written path.
    """
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=110)
    _draw_curves(ax, curves, start, logy)
    ax.set_xlabel("rollout step")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    return _save(fig, path)


def _draw_curves(ax, curves, start, logy):
    for label, values in curves.items():
        values = np.asarray(values, np.float64)
        style = _BASELINE_STYLE if "constant" in label.lower() else {}
        ax.plot(np.arange(start, start + values.size), values, label=label, **style)
    if logy and all(np.all(np.asarray(v) > 0) for v in curves.values()):
        ax.set_yscale("log")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def plot_rollout_metrics(
    metrics: dict[str, dict[str, np.ndarray]],
    path: str | pathlib.Path,
    *,
    title: str = "",
    start: int = 1,
) -> pathlib.Path:
    """Three panels per step: MSE, clot centroid error and fraction of clot outside the vessel.

    Args:
        metrics: label (model or baseline) -> ``{"mse": [S], "centroid_error": [S],
            "fraction_outside": [S]}``; a missing key leaves that panel without the curve.
        path: PNG to write. title: figure title. start: step number of the first value.
    Returns:
        The written path.
    """
    panels = (("mse", "MSE (scaled)", True), ("centroid_error", "centroid error (scaled)", True),
              ("fraction_outside", "fraction of clot outside vessel", False))
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.0), dpi=100)
    for ax, (key, label, logy) in zip(axes, panels, strict=True):
        curves = {name: m[key] for name, m in metrics.items() if key in m}
        _draw_curves(ax, curves, start, logy)
        ax.set_xlabel("rollout step")
        ax.set_ylabel(label)
    axes[2].set_ylim(-0.02, 1.02)
    fig.suptitle(title)
    return _save(fig, path)


def _save(fig, path) -> pathlib.Path:
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def equal_limits(*clouds: np.ndarray, pad: float = 0.05) -> np.ndarray:
    """One cube of axis limits containing every point: ``[3, 2]`` (min, max per axis)."""
    pts = np.concatenate([np.asarray(c, np.float64).reshape(-1, 3) for c in clouds])
    lo, hi = pts.min(0), pts.max(0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2 * (1 + pad)
    return np.stack([centre - half, centre + half], axis=1)


def animate_rollout(
    pred: np.ndarray,
    true: np.ndarray,
    node_type: np.ndarray,
    path: str | pathlib.Path,
    *,
    fps: int = 8,
    max_wall_points: int = 1500,
    title: str = "",
    labels: tuple[str, str] = ("prediction", "ground truth"),
    seed: int = 0,
    first_frame: int = 0,
) -> pathlib.Path:
    """GIF of the predicted rollout beside the ground truth, same view and equal axes.

    Args:
        pred, true: ``[n_frames, n_nodes, 3]`` positions (same units).
        node_type: ``[n_nodes]`` NodeType values; the vessel is drawn as faint grey points
            (a fixed random subset of at most ``max_wall_points``), the clot in colour.
        path: GIF to write. fps: frames per second. title: figure title.
        labels: panel titles. seed: seed of the wall subset.
        first_frame: simulation frame number of ``pred[0]`` (shown in the title).
    Returns:
        The written path.
    """
    pred, true = np.asarray(pred), np.asarray(true)
    clot = np.asarray(node_type) == NodeType.CLOT
    wall = np.flatnonzero(~clot)
    if wall.size > max_wall_points:
        wall = np.sort(np.random.default_rng(seed).choice(wall, max_wall_points, replace=False))
    lim = equal_limits(true[:, clot], pred[:, clot], true[0, wall])
    fig = plt.figure(figsize=(10, 5), dpi=80)
    artists = []
    for i, (traj, label, colour) in enumerate(((pred, labels[0], "tab:red"),
                                               (true, labels[1], "tab:blue"))):
        ax = fig.add_subplot(1, 2, i + 1, projection="3d")
        w = traj[0, wall]
        ax.scatter(w[:, 0], w[:, 1], w[:, 2], s=2, c="0.5", alpha=0.35, depthshade=False)
        c = traj[0, clot]
        artists.append(ax.scatter(c[:, 0], c[:, 1], c[:, 2], s=4, c=colour, depthshade=False))
        ax.set(xlim=lim[0], ylim=lim[1], zlim=lim[2], xlabel="x", ylabel="y", zlabel="z")
        ax.set_box_aspect((1, 1, 1))
        ax.set_title(label)
    text = fig.suptitle(title)

    def update(t):
        for art, traj in zip(artists, (pred, true), strict=True):
            c = traj[t, clot]
            art._offsets3d = (c[:, 0], c[:, 1], c[:, 2])
        last = first_frame + pred.shape[0] - 1
        text.set_text(f"{title}  frame {first_frame + t}/{last}".strip())
        return artists

    anim = FuncAnimation(fig, update, frames=pred.shape[0], blit=False)
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    anim.save(path, writer=PillowWriter(fps=fps))
    plt.close(fig)
    return path
