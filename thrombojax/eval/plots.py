"""Matplotlib figures: rollout error curves and prediction-beside-truth animations.

Every function takes plain numpy arrays, writes one file (atomically) and returns its path; none
keeps state. 3-D views (:mod:`thrombojax.plotting.scene`) use one view box for every panel, set from
the vessel and the ground truth (never the prediction), equal axis scaling, one camera, the clot
drawn above the wall, axis labels with units and the frame's time in the title; the predicted
clot is coloured by its distance to the truth. The summary figure (surrogate, constant velocity,
truth at a few frames) is :func:`thrombojax.eval.summary_plot.plot_rollout_summary`.
"""

from __future__ import annotations

import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from thrombojax.errors import ConfigError  # noqa: E402
from thrombojax.plotting.gif import render_frames, write_gif  # noqa: E402
from thrombojax.plotting.scene import save_atomic  # noqa: E402
from thrombojax.plotting.ticks import readable_value_axis  # noqa: E402
from thrombojax.types import NodeType  # noqa: E402

__all__ = [
    "plot_error_curves", "plot_rollout_metrics", "equal_limits", "rollout_figure",
    "animate_rollout",
]

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
    values = [np.asarray(v, np.float64).ravel() for v in curves.values()]
    readable_value_axis(ax, np.concatenate(values) if values else [], log=logy)
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
    fig.tight_layout()
    path = save_atomic(lambda tmp: fig.savefig(tmp, format="png"), path)
    plt.close(fig)
    return path


def equal_limits(*clouds: np.ndarray, pad: float = 0.05) -> np.ndarray:
    """One cube of axis limits containing every point: ``[3, 2]`` (min, max per axis)."""
    pts = np.concatenate([np.asarray(c, np.float64).reshape(-1, 3) for c in clouds])
    lo, hi = pts.min(0), pts.max(0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2 * (1 + pad)
    return np.stack([centre - half, centre + half], axis=1)


def _per_node(values, shape, what: str) -> np.ndarray | None:
    """``[T, N]`` magnitudes from ``[T, N]`` or ``[T, N, k]`` (vector norms), or None."""
    if values is None:
        return None
    values = np.asarray(values, np.float64)
    if values.ndim == 3:
        values = np.linalg.norm(values, axis=-1)
    if values.shape != shape:
        raise ConfigError(f"animate_rollout: {what} has shape {values.shape}, expected {shape} "
                         "(+ optional vector components)")
    return values


def _colorbar(fig, mappable, ax, label: str) -> None:
    bar = fig.colorbar(mappable, ax=ax, location="bottom", shrink=0.6, pad=0.04, fraction=0.04,
                       aspect=30, extend="max")
    bar.set_label(label, fontsize=8)
    bar.ax.tick_params(labelsize=7)


def _frame_text(title: str, frame: int, last: int, dt: float | None, time_unit: str) -> str:
    when = f"frame {frame}/{last}"
    if dt is not None:
        when += f"   t = {frame * dt:.4g} {time_unit}".rstrip()
    return f"{title}   {when}".strip()


def rollout_figure(
    pred: np.ndarray,
    true: np.ndarray,
    node_type: np.ndarray,
    *,
    max_wall_points: int = 1500,
    title: str = "",
    labels: tuple[str, str] = ("prediction", "ground truth"),
    seed: int = 0,
    first_frame: int = 0,
    dt: float | None = None,
    units: str = "",
    time_unit: str = "",
    correction: np.ndarray | None = None,
    spread: np.ndarray | None = None,
):
    """The figure of :func:`animate_rollout` and its per-frame update function.

    Returns:
        ``(figure, update, n_frames)``; ``update(t)`` draws frame ``t``; ``update.changing``
        lists the artists it changes (the clot scatters, the titles), in drawing order.
    """
    from matplotlib.colors import Normalize
    from matplotlib.lines import Line2D

    from thrombojax.plotting.scene import (
        camera_angles,
        draw_clot,
        draw_wall,
        outside_box,
        setup_axes,
        view_limits,
        wall_subset,
    )

    pred, true = np.asarray(pred, np.float64), np.asarray(true, np.float64)
    if pred.shape != true.shape or pred.ndim != 3 or pred.shape[-1] != 3:
        raise ConfigError(f"animate_rollout: pred {pred.shape} and true {true.shape} must both "
                         "be [n_frames, n_nodes, 3]")
    clot = np.asarray(node_type) == NodeType.CLOT
    correction = _per_node(correction, pred.shape[:2], "correction")
    spread = _per_node(spread, pred.shape[:2], "spread")
    wall = wall_subset(node_type, max_wall_points, seed)
    lim = view_limits(true, node_type)
    angles = camera_angles(true[0, wall] if wall.size else true[0])
    units = units or "length unit"
    error = np.linalg.norm(pred - true, axis=-1)[:, clot]
    finite = error[np.isfinite(error)]
    # errors beyond a fifth of the box are "far off" whatever their size: saturate the colour
    top = float(np.percentile(finite, 99)) if finite.size else 1.0
    err_norm = Normalize(0.0, max(min(top, (lim[0, 1] - lim[0, 0]) / 5), 1e-12))
    n_panels = 2 + (spread is not None)
    fig = plt.figure(figsize=(5.4 * n_panels, 5.6), dpi=90)
    axes = [fig.add_subplot(1, n_panels, i + 1, projection="3d") for i in range(n_panels)]
    for ax in axes:
        setup_axes(ax, lim, units, angles)
        draw_wall(ax, true[0, wall])
    arts = {
        "pred": draw_clot(axes[0], pred[0, clot], values=error[0], norm=err_norm, cmap="plasma"),
        "true": draw_clot(axes[1], true[0, clot], color="tab:blue"),
    }
    _colorbar(fig, arts["pred"], axes[0], f"clot error: distance to truth [{units}]")
    titles = [labels[0], labels[1]]
    if spread is not None:
        sp = spread[:, clot]
        sp_fin = sp[np.isfinite(sp)]
        sp_norm = Normalize(0.0, max(float(sp_fin.max()) if sp_fin.size else 1.0, 1e-12))
        arts["spread"] = draw_clot(axes[2], pred[0, clot], values=sp[0], norm=sp_norm,
                                   cmap="viridis")
        _colorbar(fig, arts["spread"], axes[2], f"ensemble spread [{units}]")
        titles.append("ensemble spread (on the prediction)")
    if correction is not None:
        arts["corr"] = axes[0].scatter([], [], [], s=28, marker="o", facecolors="none",
                                       edgecolors="black", linewidths=0.8, zorder=3,
                                       axlim_clip=True, depthshade=False)
    handles = [Line2D([], [], ls="", marker="o", color="0.55", label="vessel wall (subset)"),
               Line2D([], [], ls="", marker="o", color=plt.get_cmap("plasma")(0.6),
                      label=f"clot, {labels[0]} (colour: error)"),
               Line2D([], [], ls="", marker="o", color="tab:blue", label=f"clot, {labels[1]}")]
    if correction is not None:
        handles.append(Line2D([], [], ls="", marker="o", mfc="none", mec="black",
                              label="guard-corrected node"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=9, frameon=False)
    text = fig.suptitle("", fontsize=11, y=0.985)
    last = first_frame + pred.shape[0] - 1

    def update(t: int):
        frames = {"pred": pred[t, clot], "true": true[t, clot], "spread": pred[t, clot]}
        for key, art in arts.items():
            if key == "corr":
                hit = clot & (correction[t] > 0)
                art._offsets3d = tuple(pred[t, hit].T)
                continue
            art._offsets3d = tuple(frames[key].T)
            if key == "pred":
                art.set_array(error[t])
            elif key == "spread":
                art.set_array(spread[t, clot])
        for ax, name, traj in zip(axes, titles, (pred, true, pred), strict=False):
            n_out = int(outside_box(traj[t, clot], lim).sum())
            note = f"{n_out} clot nodes outside the view" if n_out else ""
            ax.title.set_text(f"{name}\n{note}")  # set_title would reset its position
        extra = ""
        if correction is not None:
            extra = f"   guard-corrected nodes: {int((correction[t][clot] > 0).sum())}"
        text.set_text(_frame_text(title, first_frame + t, last, dt, time_unit) + extra)
        return list(arts.values())

    for ax in axes:
        ax.set_title("", fontsize=10, color="black")
    fig.subplots_adjust(left=0.02, right=0.98, bottom=0.13, top=0.86, wspace=0.05)
    update(0)
    update.changing = [*arts.values(), *(ax.title for ax in axes), text]
    return fig, update, pred.shape[0]


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
    dt: float | None = None,
    units: str = "",
    time_unit: str = "",
    correction: np.ndarray | None = None,
    spread: np.ndarray | None = None,
) -> pathlib.Path:
    """GIF of the predicted rollout beside the ground truth, one view box and camera for both.

    The view box holds the vessel wall and the ground-truth clot (never the prediction: a
    diverging prediction leaves it, is clipped, and the panel says how many nodes are outside).
    The predicted clot is coloured by its distance to the truth (colour bar in ``units``), the
    clot is drawn above the wall, and the title gives the frame and the physical time.

    Args:
        pred, true: ``[n_frames, n_nodes, 3]`` positions (same units).
        node_type: ``[n_nodes]`` NodeType values; the vessel is drawn as faint grey points
            (a fixed random subset of at most ``max_wall_points``), the clot in colour.
        path: GIF to write. fps: frames per second. title: figure title.
        labels: panel titles. seed: seed of the wall subset.
        first_frame: simulation frame number of ``pred[0]``.
        dt: time between frames (the title shows ``t = frame * dt``); None: no time.
        units: length unit of the positions (axis labels, colour bars). time_unit: of ``dt``.
        correction: optional ``[n_frames, n_nodes]`` (or ``[..., 3]``) guard corrections;
            clot nodes with a non-zero correction are circled in black.
        spread: optional ``[n_frames, n_nodes]`` (or ``[..., 3]``) ensemble spread, drawn in a
            third panel on the predicted clot.
    Returns:
        The written path.
    """
    fig, update, n_frames = rollout_figure(
        pred, true, node_type, max_wall_points=max_wall_points, title=title, labels=labels,
        seed=seed, first_frame=first_frame, dt=dt, units=units, time_unit=time_unit,
        correction=correction, spread=spread)

    try:  # the axes, wall, legend and colour bars drawn once (thrombojax/plotting/gif.py)
        frames = render_frames(fig, update, n_frames, update.changing)
    finally:
        plt.close(fig)
    return save_atomic(lambda tmp: write_gif(frames, tmp, fps), path)
