"""The training picture: best epoch, readable log ticks, learning-rate curve, PNG written."""

from __future__ import annotations

import json

import numpy as np
from PIL import Image

from thrombojax.train.plots import best_epoch, loss_figure, plot_losses, read_metrics


def _records(n=12, val=True):
    out = []
    for e in range(1, n + 1):
        r = {"epoch": e, "step": 10 * e, "train_loss": 1.0 / e, "train_mse": 2e-4 / e ** 0.2,
             "lr": 1e-3 * (0.5 + 0.5 * np.cos(np.pi * e / n)), "time_s": 1.0}
        if val:
            r |= {"val_loss": 1.2 / e, "val_mse": 3e-4 * (1 + (e - 8) ** 2 / 100)}
        out.append(r)
    return out


def test_best_epoch_is_the_lowest_validation_mse_else_training_mse():
    assert best_epoch(_records())[:1] == (8,)
    assert best_epoch(_records())[2] == "val_mse"
    assert best_epoch(_records(val=False))[0] == 12
    assert best_epoch([]) is None


def test_loss_figure_has_readable_ticks_lr_and_best_marker(tmp_path):
    fig = loss_figure(_records())
    loss_ax, mse_ax, lr_ax = fig.axes
    fig.canvas.draw()
    lo, hi = mse_ax.get_ylim()
    shown = [t for t in mse_ax.get_yticks() if lo <= t <= hi]
    assert len(shown) >= 3  # the MSE spans less than a decade and still gets labelled ticks
    assert all(lab.get_text() for lab in mse_ax.get_yticklabels() if lo <= lab.get_position()[1]
               <= hi)
    assert len(lr_ax.lines[0].get_xdata()) == 12
    assert any("best: epoch 8" in t.get_text() for t in mse_ax.get_legend().get_texts())
    assert all(any(np.allclose(ln.get_xdata(), 8) for ln in ax.lines) for ax in fig.axes)


def test_plot_losses_writes_a_png(tmp_path):
    path = tmp_path / "metrics.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in _records()) + '{"note": 1}\n')
    assert len(read_metrics(path)) == 12
    png = plot_losses(path, tmp_path / "loss.png")
    assert Image.open(png).size[0] > 1000
    assert not list(tmp_path.glob(".*tmp"))


def test_value_axis_is_linear_within_a_decade_and_log_with_1_2_5_labels_beyond():
    from matplotlib.figure import Figure

    from thrombojax.plotting.ticks import readable_value_axis, short_number

    assert [short_number(v) for v in (2e-4, 0.5, 30.0, 1e5)] == ["2e-4", "0.5", "30", "1e5"]
    ax = Figure().subplots()
    ax.plot([1, 2], [2.1, 2.6])
    readable_value_axis(ax, [2.1, 2.6])
    assert ax.get_yscale() == "linear"
    ax = Figure().subplots()
    ax.plot([1, 2], [1e-4, 3e-3])
    readable_value_axis(ax, [1e-4, 3e-3])
    ax.figure.canvas.draw()
    lo, hi = ax.get_ylim()
    labels = [lab.get_text() for lab in ax.get_yticklabels() if lo <= lab.get_position()[1] <= hi]
    assert ax.get_yscale() == "log" and {"1e-4", "2e-4", "5e-4", "1e-3", "2e-3"} <= set(labels)
