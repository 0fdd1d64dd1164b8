"""experiments/clot_speed.py: the true clot's speed per frame and the travel-only rules."""

import importlib.util
import pathlib

import numpy as np
import pytest
from dataset_factory import accelerating_sims

from thrombojax.io.hdf5 import write_dataset
from thrombojax.types import NodeType

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _module():
    spec = importlib.util.spec_from_file_location("clot_speed",
                                                  ROOT / "experiments" / "clot_speed.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_speed_travel_and_the_start_speed_rule_on_a_known_motion():
    """A clot at speed 0.1 + 0.01 t per frame along x, then turning: the record's speed, its
    travel and the start-speed rule's error are those of the motion; straight, no curvature."""
    m = _module()
    n_frames, skip = 12, 4
    t = np.arange(n_frames, dtype=np.float64)
    x = 0.1 * t + 0.005 * t * (t - 1)  # x_{t+1} - x_t = 0.1 + 0.01 t
    nt = np.array([NodeType.VESSEL] * 3 + [NodeType.CLOT] * 2)
    pos = np.zeros((n_frames, 5, 3))
    pos[:, :3, 1] = [-1.0, 0.0, 1.0]  # wall nodes on the y axis, 1 from the path
    pos[:, :3, 0] = 50.0
    pos[:, 3:, 0] = x[:, None]
    rec = m.simulation_record(pos, nt, skip, r=1.0, smooth=1)
    expect = 0.1 + 0.01 * np.arange(skip, n_frames - 1)
    np.testing.assert_allclose(rec["speed"], expect, atol=1e-12)
    assert rec["start_speed"] == pytest.approx(0.1 + 0.01 * (skip - 1))
    assert rec["travel"] == pytest.approx(expect.sum())
    np.testing.assert_allclose(rec["curvature"], 0.0, atol=1e-6)
    assert len(rec["clearance"]) == len(rec["speed"]) == rec["steps"]
    rows, pooled = m.summarise({"a": rec, "b": rec})
    assert rows[0][7] == pytest.approx(expect.sum() - rec["start_speed"] * rec["steps"])
    assert rows[0][8] == pytest.approx(0.0, abs=1e-12)  # the other simulation is the same
    with pytest.raises(ValueError, match="no rollout window"):
        m.simulation_record(pos[:skip + 1], nt, skip, r=1.0, smooth=1)


def test_clearance_rule_is_exact_when_speed_is_a_line_of_clearance():
    """Speeds that are exactly 0.1 + 0.2 * clearance in every simulation: the fit recovers the
    line and the closed loop along the true track ends where the true clot does; a rule fitted
    to a slower simulation ends behind; clearances that never vary give NaN."""
    m = _module()

    def sim(clear, offset=0.0):
        speed = 0.1 + offset + 0.2 * np.asarray(clear)
        return {"speed": speed.tolist(), "clearance": list(clear), "travel": float(speed.sum()),
                "steps": len(clear), "start_speed": float(speed[0]),
                "curvature": [0.0] * len(clear)}

    a, b = sim(np.linspace(0.8, 1.2, 30)), sim(np.linspace(1.1, 0.7, 30))
    assert m.clearance_rule(a, [b]) == pytest.approx(0.0, abs=1e-9)
    assert m.clearance_rule(b, [a]) == pytest.approx(0.0, abs=1e-9)
    slower = sim(np.linspace(1.0, 0.6, 30), offset=-0.05)
    assert m.clearance_rule(a, [slower]) < -1.0  # 0.05 r per frame slower over 30 steps
    flat = sim(np.full(30, 0.9))
    assert np.isnan(m.clearance_rule(a, [flat]))
    rows, _ = m.summarise({"a": a, "b": b})
    assert rows[0][9] == pytest.approx(0.0, abs=1e-9)


def test_script_writes_its_outputs_and_refuses_to_replace_them(tmp_path):
    m = _module()
    data = write_dataset(tmp_path / "acc.h5", accelerating_sims(n_sims=2, n_nodes=40,
                                                                n_frames=6),
                         name="acc", source="test")
    out = tmp_path / "speed"
    assert m.main(["--dataset", str(data), "--out", str(out)]) == 0
    assert "- jax:" in (out / "table.md").read_text()
    assert (out / "speed.png").stat().st_size > 0 and (out / "clot_speed.json").is_file()
    with pytest.raises(Exception, match="exists|force"):
        m.main(["--dataset", str(data), "--out", str(out)])


def test_exit_crossing_and_the_exit_timing_rule_on_a_straight_tube():
    """A clot moving along x at 0.5 per frame past a wall that ends at x = 10: it passes the
    far end after (10 - x0) / 0.5 steps, at that distance; the exit-timing rule, given another
    simulation whose clot takes as many steps to its exit, ends exactly where the true one does,
    and a clot that never leaves the tube has no exit."""
    m = _module()
    wall = np.stack([np.linspace(-2.0, 10.0, 25), np.ones(25), np.zeros(25)], axis=-1)
    track = np.stack([0.5 + 0.5 * np.arange(30), np.zeros(30), np.zeros(30)], axis=-1)
    steps, distance = m.exit_crossing(track, wall)
    assert steps == pytest.approx(19.0) and distance == pytest.approx(9.5)
    assert m.exit_crossing(track[:10], wall) is None  # never past x = 10

    def sim(speed, exit_steps, steps=29):
        return {"steps": steps, "travel": speed * steps, "exit_steps": exit_steps,
                "exit_distance": None if exit_steps is None else speed * exit_steps}

    slow, fast = sim(0.3, 20.0), sim(0.6, 20.0)  # the same frame of exit, twice the speed
    assert m.exit_rule(slow, [fast]) == pytest.approx(0.0, abs=1e-12)
    assert m.exit_rule(fast, [slow]) == pytest.approx(0.0, abs=1e-12)
    assert m.exit_rule(slow, [sim(0.6, 25.0)]) < 0  # the others exit later: the rule is slow
    assert np.isnan(m.exit_rule(slow, [sim(0.6, None)]))


def test_parameter_rule_recovers_a_speed_set_by_one_parameter():
    """Speeds per frame ``exp(1 + 0.5 friction) * dt``: leaving each simulation out, the ridge
    fit on the others' friction (the constant inputs dropped) predicts it within a few per cent
    at the smallest weight, which is the one reported; without the attributes every error is
    NaN."""
    m = _module()
    rng = np.random.default_rng(0)
    sims = {}
    for i, (friction, dt) in enumerate(zip(rng.uniform(0.1, 0.3, 8), rng.uniform(0.5, 0.9, 8),
                                           strict=True)):
        speed = np.exp(1.0 + 0.5 * friction) * dt
        sims[f"s{i}"] = {"steps": 100, "travel": 100 * speed, "dt": float(dt),
                         "parameters": {"friction": float(friction), "young": 1.0}}
    rule = m.parameter_rule(sims)
    assert rule["inputs"] == ["friction"] and rule["lambda"] == min(m.RIDGE)
    for name, error in rule["errors"].items():
        assert abs(error) < 0.02 * sims[name]["travel"], (name, error)
    bare = {k: {"steps": v["steps"], "travel": v["travel"]} for k, v in sims.items()}
    assert all(np.isnan(e) for e in m.parameter_rule(bare)["errors"].values())
