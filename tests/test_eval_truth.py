"""Errors in vessel radii and single-step phases (thrombojax/eval/physical.py, phases.py)."""

from __future__ import annotations

import numpy as np
import pytest

from thrombojax.data.scaling import Scaling
from thrombojax.eval.metrics import fit_vessel_wall
from thrombojax.eval.phases import PHASES, exit_frame, phase_summary, window_phases
from thrombojax.eval.physical import RadiusUnits, radius_units, summary_in_radii
from thrombojax.types import NodeType


def _straight_tube(length=10.0, radius=1.0, rings=41, around=16):
    """Wall nodes of a tube along x from 0 to ``length`` (both ends open)."""
    ang = np.linspace(0, 2 * np.pi, around, endpoint=False)
    return np.concatenate([np.stack([np.full(around, x), radius * np.cos(ang),
                                     radius * np.sin(ang)], 1)
                           for x in np.linspace(0, length, rings)])


def _moving_clot(x_start, speed, n_frames, wall, seed=0):
    """A clot cloud (radius 0.6) translating along x: ([T, N, 3] with the wall, node_type)."""
    rng = np.random.default_rng(seed)
    clot = rng.uniform(-0.6, 0.6, (40, 3))
    clot[:, 0] = rng.uniform(0.0, 1.5, 40)
    frames = [np.concatenate([clot + [x_start + speed * t, 0, 0], wall]) for t in range(n_frames)]
    node_type = np.r_[np.full(40, NodeType.CLOT), np.full(len(wall), NodeType.VESSEL)]
    return np.stack(frames), node_type


def test_exit_frame_is_the_first_frame_past_the_outlet():
    wall = _straight_tube()
    pos, node_type = _moving_clot(2.0, 1.0, 12, wall)  # clot front at 3.5 + t: past 10 at t=7
    w = fit_vessel_wall(pos[0], node_type)
    assert exit_frame(w, pos, node_type == NodeType.CLOT) == 7
    still, _ = _moving_clot(2.0, 0.2, 12, wall)  # front reaches 5.7: never leaves
    assert exit_frame(w, still, node_type == NodeType.CLOT) is None
    # a clot entering through the inlet (partly past it at frame 0) is not an exit
    entering, _ = _moving_clot(-1.0, 0.3, 12, wall)
    assert exit_frame(w, entering, node_type == NodeType.CLOT) is None


def test_exit_frame_ignores_holes_in_the_wall_cloud():
    """A gap in a sparse wall cloud looks like an open end to the angular-gap test; a clot
    passing it inside the vessel has not left (the wall goes on beyond the gap)."""
    wall = _straight_tube()
    hole = (np.abs(wall[:, 0] - 6.0) < 0.3) & (wall[:, 1] > 0.5)  # 3 rings x 5 nodes
    wall = wall[~hole]
    pos, node_type = _moving_clot(2.0, 0.4, 12, wall)  # front from 3.5 to 7.9, past the hole
    w = fit_vessel_wall(pos[0], node_type)
    assert (np.abs(w.rim_dir).sum(1) > 0)[np.abs(w.points[:, 0] - 6.0) < 1.0].any()
    assert exit_frame(w, pos, node_type == NodeType.CLOT) is None
    assert exit_frame(w, pos, node_type == NodeType.CLOT, k=1) is not None  # without the test


def test_window_phases_split_at_skip_frames_and_exit():
    t = np.arange(1, 11)  # windows (t-1, t, t+1) of a 12-frame simulation
    ph = window_phases(t, skip_frames=4, exit_at=9)
    assert set(ph) == set(PHASES)
    assert t[ph["start"]].tolist() == [1, 2, 3]
    assert t[ph["rollout"]].tolist() == list(range(4, 11))
    assert t[ph["exit"]].tolist() == [8, 9, 10]  # target frame t + 1 >= 9
    assert t[ph["rollout_before_exit"]].tolist() == [4, 5, 6, 7]
    assert not window_phases(t, skip_frames=0, exit_at=None)["exit"].any()


def test_phase_summary_scaled_radii_and_ratio():
    units = RadiusUnits(scale=5.0, radius=2.0, source="test")  # 2.5 r per scaled unit
    model = np.array([1.0, 1.0, 3.0, 3.0])
    cv = np.array([2.0, 2.0, 1.0, 1.0])
    ph = window_phases(np.array([1, 2, 3, 4]), skip_frames=3, exit_at=None)
    s = phase_summary(model, cv, ph, units)
    assert s["start"]["mse"] == 1.0 and s["start"]["ratio_to_cv"] == 0.5
    assert s["rollout"]["ratio_to_cv"] == 3.0 and s["all"]["windows"] == 4
    assert s["rollout"]["mse_r2"] == pytest.approx(3.0 * 2.5**2)
    assert s["rollout"]["rmse_r"] == pytest.approx(np.sqrt(3.0) * 2.5)
    assert s["rollout"]["constant_velocity_rmse_r"] == pytest.approx(2.5)
    assert s["exit"]["windows"] == 0 and s["exit"]["mse"] is None
    assert s["exit"]["ratio_to_cv"] is None


def test_summary_in_radii_converts_and_divides_by_cv():
    units = RadiusUnits(scale=4.0, radius=0.5, source="test")  # 8 r per scaled unit
    summary = {
        "mgn": {"mse@1": 0.01, "mse@full": 0.04, "final_centroid_error": 0.3,
                "max_fraction_outside": 0.1},
        "constant velocity": {"mse@1": 0.02, "mse@full": 0.01, "final_centroid_error": 0.1,
                              "max_fraction_outside": 0.0},
        "ground truth": {"max_fraction_outside": 0.0},
    }
    out = summary_in_radii(summary, units)
    assert out["mgn"]["mse@full_r2"] == pytest.approx(0.04 * 64)
    assert out["mgn"]["rmse@full_r"] == pytest.approx(0.2 * 8)
    assert out["mgn"]["final_centroid_error_r"] == pytest.approx(2.4)
    assert out["mgn"]["ratio_to_cv"] == pytest.approx(
        {"mse@1": 0.5, "mse@full": 4.0, "final_centroid_error": 3.0})
    assert "ratio_to_cv" not in out["constant velocity"]
    assert "ratio_to_cv" not in out["ground truth"]
    assert summary["mgn"].keys() == {"mse@1", "mse@full", "final_centroid_error",
                                     "max_fraction_outside"}  # the input is not modified


def test_radius_units_from_scaling_and_dataset():
    class FakeDataset:
        attrs = {"units": "mm", "vessel_radius": 1.5}

    u = radius_units(Scaling(center=np.zeros(3), scale=np.asarray(6.0)), FakeDataset())
    assert u.factor == pytest.approx(4.0) and u.units == "mm"
    d = u.to_dict()
    assert d["vessel_radius"] == 1.5 and d["scale"] == 6.0
    assert d["vessel_radius_source"] == "file attribute vessel_radius"
    assert "MSE_r2 = MSE_scaled * (scale / r)^2" in d["formula"]
    assert u.mse(0.25) == pytest.approx(4.0) and u.length(np.array([1.0, 2.0])).tolist() == [4, 8]
