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
