"""The training picture: loss, MSE and learning rate per epoch, with the best epoch marked.

Read from a run's ``metrics.jsonl`` (one JSON record per epoch, written by
:mod:`thrombojax.train.loop`). The best epoch is the one the loop keeps as the ``best``
checkpoint: the last epoch (``select_by="last"``), the lowest validation rollout MSE
(``select_by="rollout"``), else the lowest validation MSE, or the lowest training MSE without a
validation split.
Value axes are logarithmic when the values span a decade or more, else linear, and always
carry several labelled ticks (:mod:`thrombojax.plotting.ticks`).
"""

from __future__ import annotations

import json
import os
import pathlib

import numpy as np

from thrombojax.plotting.ticks import readable_value_axis

__all__ = ["read_metrics", "best_epoch", "loss_figure", "plot_losses"]


def read_metrics(metrics_path: str | pathlib.Path) -> list[dict]:
    """The per-epoch records of ``metrics.jsonl`` (lines without ``epoch`` are skipped)."""
    lines = pathlib.Path(metrics_path).read_text().splitlines()
    records = [json.loads(ln) for ln in lines if ln.strip()]
    return [r for r in records if "epoch" in r and "train_loss" in r]


def best_epoch(records: list[dict], select_by: str = "mse") -> tuple[int, float, str] | None:
    """``(epoch, value, key)`` of the epoch the ``best`` checkpoint holds: the last record's
    (``select_by="last"``; its ``val_mse``, else ``train_mse``), else the lowest
    ``val_rollout_mse`` (a run that picks its best checkpoint by the validation rollout), else
    ``val_mse``, else ``train_mse``; None if none is finite (a rollout that diverged is logged
    as ``null``)."""
    key = next((k for k in ("val_rollout_mse", "val_mse") if any(k in r for r in records)),
               "train_mse")
    if select_by == "last":
        key = "val_mse" if any("val_mse" in r for r in records) else "train_mse"
        records = records[-1:]
    scored = [(r[key], r["epoch"]) for r in records
              if r.get(key) is not None and np.isfinite(r[key])]
    if not scored:
        return None
    value, epoch = min(scored)
    return int(epoch), float(value), key


def loss_figure(records: list[dict], select_by: str = "mse"):
    """The figure of :func:`plot_losses` from per-epoch records (a matplotlib ``Figure``)."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    best = best_epoch(records, select_by)
    ratio = [(r["epoch"], r["val_rollout_cv_ratio"]) for r in records
             if r.get("val_rollout_cv_ratio") is not None]
    fig = Figure(figsize=(17 if ratio else 13, 3.8), dpi=100)
    axes = fig.subplots(1, 4 if ratio else 3)
    if ratio:
        _rollout_panel(axes[3], ratio)
    for ax, key, title in ((axes[0], "loss", "loss (normalised acceleration)"),
                           (axes[1], "mse", "MSE of next positions (scaled coords)")):
        shown = []
        for split, colour in (("train", "tab:blue"), ("val", "tab:orange")):
            pts = [(r["epoch"], r[f"{split}_{key}"]) for r in records if f"{split}_{key}" in r]
            if pts:
                ep, val = (np.asarray(v, np.float64) for v in zip(*pts, strict=True))
                val = np.maximum(val, 1e-30)
                ax.plot(ep, val, label=split, color=colour, marker="." if len(ep) < 30 else "")
                shown.extend(val)
        readable_value_axis(ax, shown)
        ax.set_title(title, fontsize=10)
        ax.set_ylabel(key)
    axes[2].plot([r["epoch"] for r in records if "lr" in r],
                 [r["lr"] for r in records if "lr" in r], color="tab:green")
    axes[2].set_title("learning rate (end of epoch)", fontsize=10)
    axes[2].set_ylabel("learning rate")
    axes[2].ticklabel_format(axis="y", style="sci", scilimits=(-2, 2))
    if best is not None:
        epoch, value, key = best
        for ax in axes:
            ax.axvline(epoch, color="0.3", linestyle=":", linewidth=1.0)
        on = axes[3] if key == "val_rollout_mse" else axes[1]
        shown = dict(ratio)[epoch] if key == "val_rollout_mse" else value
        on.plot([epoch], [max(shown, 1e-30)], marker="*", markersize=12, color="crimson",
                linestyle="", label=f"best: epoch {epoch} ({key} {value:.3g})")
    for ax in axes:
        ax.set_xlabel("epoch")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(alpha=0.3, which="major")
    for ax in (*axes[:2], *axes[3:]):
        ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def _rollout_panel(ax, ratio: list[tuple[int, float]]) -> None:
    """The validation rollout's full-length MSE over constant velocity's, per epoch."""
    ep, val = (np.asarray(v, np.float64) for v in zip(*ratio, strict=True))
    ax.plot(ep, np.maximum(val, 1e-30), color="tab:purple", marker="." if len(ep) < 30 else "",
            label="validation rollout")
    ax.axhline(1.0, color="0.4", linestyle="--", linewidth=1.0, label="constant velocity")
    readable_value_axis(ax, [*val, 1.0])
    ax.set_title("rollout MSE / constant velocity (model alone)", fontsize=10)
    ax.set_ylabel("ratio")


def plot_losses(metrics_path: str | pathlib.Path, out_png: str | pathlib.Path,
                select_by: str = "mse") -> pathlib.Path:
    """Plot loss, MSE and learning rate per epoch from ``metrics.jsonl``.

    Panels: training / validation loss (normalised acceleration), training / validation MSE of
    the next positions (scaled coordinates), both log scale with the best epoch marked, the
    learning rate at the end of each epoch and, when the run measured it
    (``select_by="rollout"``), the validation rollout's MSE over constant velocity's;
    ``select_by``: the run's (:class:`~thrombojax.train.config.TrainConfig`), which epoch the
    ``best`` checkpoint holds (:func:`best_epoch`).

    Returns:
        The PNG path (written atomically).
    """
    fig = loss_figure(read_metrics(metrics_path), select_by)
    out_png = pathlib.Path(out_png)
    tmp = out_png.with_name(f".{out_png.name}.tmp")
    fig.savefig(tmp, format="png")
    os.replace(tmp, out_png)  # atomic: a reader never sees half a picture
    return out_png
