"""Figures: files are written, the view box holds the vessel and the truth (not a diverging
prediction), the GIF has one frame per rollout frame, optional overlays are drawn."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from thrombojax.eval.plots import (
    animate_rollout,
    equal_limits,
    plot_error_curves,
    plot_rollout_metrics,
    rollout_figure,
)
from thrombojax.eval.summary_plot import default_summary_frames, plot_rollout_summary
from thrombojax.plotting.scene import camera_angles, view_limits
from thrombojax.types import NodeType


def test_equal_limits_is_a_cube_containing_all_points():
    a = np.array([[0, 0, 0], [4, 1, 0]], float)
    b = np.array([[1, -2, 0.5]], float)
    lim = equal_limits(a, b, pad=0.0)
    np.testing.assert_allclose(lim[:, 1] - lim[:, 0], 4.0)
    assert (lim[:, 0] <= np.minimum(a.min(0), b.min(0))).all()
    assert (lim[:, 1] >= np.maximum(a.max(0), b.max(0))).all()


def _scene(n_frames=4, seed=0):
    """A clot of 10 nodes moving along x inside a 20-node wall, and a prediction that diverges."""
    rng = np.random.default_rng(seed)
    true = np.repeat(rng.normal(size=(1, 30, 3)), n_frames, axis=0)
    true[:, :10, 0] += np.arange(n_frames)[:, None] * 0.3
    node_type = np.array([NodeType.CLOT] * 10 + [NodeType.VESSEL] * 20)
    pred = true + 0.05
    pred[:, :3] += np.arange(n_frames)[:, None, None] * 100.0  # three nodes fly away
    return pred, true, node_type


def _inside(points, lo, hi):
    return bool(((points >= lo) & (points <= hi)).all())


def test_plots_and_gif(tmp_path):
    steps = np.arange(1, 6)
    png = plot_error_curves({"mgn": 1e-3 * steps, "constant velocity": 2e-3 * steps},
                            tmp_path / "err.png")
    assert Image.open(png).size[0] > 300
    png = plot_rollout_metrics(
        {"mgn": {"mse": 1e-3 * steps, "centroid_error": 0.1 * steps,
                 "fraction_outside": np.zeros(5)}}, tmp_path / "m.png", title="t")
    assert png.exists()
    pred, true, node_type = _scene()
    gif = animate_rollout(pred, true, node_type, tmp_path / "r.gif", max_wall_points=15,
                          dt=0.5, units="mm")
    img = Image.open(gif)
    assert img.n_frames == 4


def test_view_box_holds_vessel_and_truth_not_the_diverging_prediction():
    pred, true, node_type = _scene()
    fig, update, n = rollout_figure(pred, true, node_type, dt=0.5, units="mm", first_frame=7)
    axes = [ax for ax in fig.axes if ax.name == "3d"]
    assert len(axes) == 2
    for ax in axes:
        lo = np.array([ax.get_xlim()[0], ax.get_ylim()[0], ax.get_zlim()[0]])
        hi = np.array([ax.get_xlim()[1], ax.get_ylim()[1], ax.get_zlim()[1]])
        assert _inside(true.reshape(-1, 3), lo, hi)
        assert not _inside(pred[-1], lo, hi)
        np.testing.assert_allclose(hi - lo, (hi - lo)[0])  # equal axes
        assert ax.get_xlabel() == "x [mm]"
    update(n - 1)
    assert "frame 10/10" in fig._suptitle.get_text()
    assert "t = 5 " in fig._suptitle.get_text() + " "
    assert "3 clot nodes outside the view" in axes[0].get_title()
    assert "outside" not in axes[1].get_title()


def test_gif_draws_guard_corrections_and_ensemble_spread(tmp_path):
    pred, true, node_type = _scene()
    correction = np.zeros(pred.shape)
    correction[2, 5:8, 1] = 0.1  # three clot nodes corrected at frame 2
    spread = np.abs(pred - true).sum(-1)
    fig, update, _ = rollout_figure(pred, true, node_type, correction=correction, spread=spread)
    assert sum(ax.name == "3d" for ax in fig.axes) == 3
    update(2)
    assert "guard-corrected nodes: 3" in fig._suptitle.get_text()
    circles = fig.axes[0].collections[-1]
    assert len(circles._offsets3d[0]) == 3
    update(1)
    assert len(circles._offsets3d[0]) == 0
    with pytest.raises(ValueError, match="spread"):
        rollout_figure(pred, true, node_type, spread=spread[:, :5])
    gif = animate_rollout(pred, true, node_type, tmp_path / "g.gif", correction=correction,
                          spread=spread)
    assert Image.open(gif).n_frames == 4


def test_camera_looks_across_the_plane_of_a_flat_vessel():
    theta = np.linspace(0, np.pi / 2, 50)
    arc = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=1)  # in z = 0
    elev, _ = camera_angles(arc, tilt=0.0)
    assert elev == pytest.approx(90.0, abs=1e-6)
    elev, _ = camera_angles(arc, tilt=30.0)
    assert elev == pytest.approx(60.0, abs=1e-6)


def test_rollout_summary_figure(tmp_path):
    pred, true, node_type = _scene(n_frames=6)
    const = true + np.arange(6)[:, None, None] * 0.2
    assert default_summary_frames(6).tolist() == [0, 2, 3, 5]
    assert default_summary_frames(2).tolist() == [0, 1]
    png = plot_rollout_summary(true, pred, const, node_type, tmp_path / "s.png", dt=0.1,
                               units="mm", first_frame=5, frames=[0, 5])
    img = Image.open(png)
    assert img.size[0] > 600 and img.size[1] > 600
    lim = view_limits(true, node_type)
    assert _inside(true.reshape(-1, 3), lim[:, 0], lim[:, 1])
    with pytest.raises(ValueError, match="frames"):
        plot_rollout_summary(true, pred, const, node_type, tmp_path / "x.png", frames=[6])
    with pytest.raises(ValueError, match="shape"):
        plot_rollout_summary(true, pred[:, :5], const, node_type, tmp_path / "x.png")


def test_rollout_summary_row_labels_clear_the_first_panels_z_axis(tmp_path, monkeypatch):
    """Each row's name stands in the figure's margin beside its row, not on the first panel's
    z axis (its label and ticks). A long wavy vessel seen as ClotEntry's are (the camera then
    puts the z axis on the panel's left)."""
    import matplotlib.text

    import thrombojax.eval.summary_plot as summary_plot

    t = np.linspace(-30.0, 30.0, 400)
    along, across = np.array([0.89, -0.17, 0.43]), np.array([0.37, -0.30, -0.88])
    wall = (t[:, None] * along + 2.0 * np.sin(t / 5)[:, None] * across
            + 0.5 * np.cos(t)[:, None] * np.cross(along, across))
    clot = np.random.default_rng(0).normal(0.0, 1.0, (50, 3)) + wall[100]
    true = np.stack([np.concatenate([clot + i * along, wall]) for i in range(6)])
    node_type = np.array([NodeType.CLOT] * 50 + [NodeType.VESSEL] * 400)
    figures = []
    monkeypatch.setattr(summary_plot.plt, "close", figures.append)  # keep the figure
    labels = ("mgn", "constant velocity", "ground truth")
    plot_rollout_summary(true, true + 0.1, true + 0.2, node_type, tmp_path / "s.png",
                         units="mm", frames=[0, 5], labels=labels)
    fig = figures[0]
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    names = {t.get_text(): t.get_window_extent(renderer)
             for t in fig.findobj(matplotlib.text.Text) if t.get_text() in labels}
    assert sorted(names) == sorted(labels)
    first_column = fig.axes[0:6:2]  # two frames per row
    z_axes = [ax.zaxis.get_tightbbox(renderer) for ax in first_column]
    assert z_axes[0].x0 < first_column[0].get_window_extent(renderer).x0  # z axis on the left
    for ax, label in zip(first_column, labels, strict=True):
        box = names[label]
        assert not any(box.overlaps(z) for z in z_axes), label
        panel = ax.get_window_extent(renderer)
        assert panel.y0 < (box.y0 + box.y1) / 2 < panel.y1, label


def test_gif_frames_equal_full_redraws_and_matplotlibs_gif(tmp_path):
    """The static parts are drawn once (thrombojax/plotting/gif.py): every frame still equals
    a full redraw pixel for pixel, and the GIF equals the one FuncAnimation + PillowWriter
    write, byte for byte."""
    from matplotlib import pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    from thrombojax.plotting.gif import render_frames

    pred, true, node_type = _scene()
    correction = np.zeros(pred.shape)
    correction[2, 5:8, 1] = 0.1
    spread = np.abs(pred - true).sum(-1)
    kwargs = dict(correction=correction, spread=spread, dt=0.5, units="mm")
    fig, update, n = rollout_figure(pred, true, node_type, **kwargs)
    frames = render_frames(fig, update, n, update.changing)
    assert not any(a.get_animated() for a in update.changing)  # left as they were
    for t in (2, 1, 3, 0):
        update(t)
        fig.canvas.draw()
        full = np.asarray(fig.canvas.buffer_rgba())[..., :3]
        np.testing.assert_array_equal(np.asarray(frames[t]), full, err_msg=f"frame {t}")
    plt.close(fig)
    ours = animate_rollout(pred, true, node_type, tmp_path / "ours.gif", **kwargs)
    fig, update, n = rollout_figure(pred, true, node_type, **kwargs)
    FuncAnimation(fig, update, frames=n).save(tmp_path / "mpl.gif", writer=PillowWriter(fps=8))
    plt.close(fig)
    assert ours.read_bytes() == (tmp_path / "mpl.gif").read_bytes()
