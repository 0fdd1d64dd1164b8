"""Figures: files are written, axes are equal, the GIF has one frame per rollout frame."""

from __future__ import annotations

import numpy as np
from PIL import Image

from thrombojax.eval.plots import (
    animate_rollout,
    equal_limits,
    plot_error_curves,
    plot_rollout_metrics,
)
from thrombojax.types import NodeType


def test_equal_limits_is_a_cube_containing_all_points():
    a = np.array([[0, 0, 0], [4, 1, 0]], float)
    b = np.array([[1, -2, 0.5]], float)
    lim = equal_limits(a, b, pad=0.0)
    np.testing.assert_allclose(lim[:, 1] - lim[:, 0], 4.0)
    assert (lim[:, 0] <= np.minimum(a.min(0), b.min(0))).all()
    assert (lim[:, 1] >= np.maximum(a.max(0), b.max(0))).all()


def test_plots_and_gif(tmp_path):
    steps = np.arange(1, 6)
    png = plot_error_curves({"mgn": 1e-3 * steps, "constant velocity": 2e-3 * steps},
                            tmp_path / "err.png")
    assert Image.open(png).size[0] > 300
    png = plot_rollout_metrics(
        {"mgn": {"mse": 1e-3 * steps, "centroid_error": 0.1 * steps,
                 "fraction_outside": np.zeros(5)}}, tmp_path / "m.png", title="t")
    assert png.exists()
    rng = np.random.default_rng(0)
    true = np.repeat(rng.normal(size=(1, 30, 3)), 4, axis=0)
    true[:, :10, 0] += np.arange(4)[:, None] * 0.3
    node_type = np.array([NodeType.CLOT] * 10 + [NodeType.VESSEL] * 20)
    gif = animate_rollout(true + 0.05, true, node_type, tmp_path / "r.gif", max_wall_points=15)
    img = Image.open(gif)
    assert img.n_frames == 4
