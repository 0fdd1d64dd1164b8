"""evaluate / rollout commands end to end on a tiny synthetic dataset and a 1-epoch run."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from thrombojax.cli import main
from thrombojax.eval.bench import synthetic_cloud
from thrombojax.types import NodeType


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    from thrombojax.io.hdf5 import Simulation, write_dataset
    from thrombojax.train.loop import train

    root = tmp_path_factory.mktemp("eval")
    sims = []
    for i in range(4):
        _, x, node_type = synthetic_cloud(160, clot_fraction=0.25, seed=i)
        frames = np.repeat(x[None], 12, axis=0)
        clot = node_type == NodeType.CLOT
        t = np.arange(12, dtype=np.float32)[:, None]
        frames[:, clot, 0] += 0.001 * t + 0.0002 * (1 + 0.1 * i) * t**2
        sims.append(Simulation(name=f"sim_{i}", positions=frames * 10.0,
                               node_type=node_type.astype(np.int8),
                               attrs={"dt": 0.01, "solver_wall_time_s": 2.0}))
    data = write_dataset(root / "tiny.h5", sims, name="tiny-bend", source="test")
    run = root / "run"
    train(data, "mgn", run, epochs=1, tiny=True, n_val=1, batch_size=2, progress=False)
    return data, run, root


def _times(path, tag, key):
    import xml.etree.ElementTree as ET

    return [float(e.get(key)) for e in ET.parse(path).getroot().iter(tag)]


def test_evaluate_command_writes_json_and_table(tiny_run, capsys):
    data, run, root = tiny_run
    assert main(["evaluate", "--run", str(run), "--dataset", str(data), "--out",
                 str(root / "ev"), "--quiet"]) == 0
    res = json.loads((root / "ev" / "evaluate.json").read_text())
    test_sim = json.loads((run / "config.json").read_text())["split"]["test"][0]
    assert list(res["simulations"]) == [test_sim]
    assert res["simulations"][test_sim]["windows"] == 10
    assert res["mse"] > 0 and res["constant_velocity_mse"] > 0
    assert "constant velocity MSE" in (root / "ev" / "evaluate.md").read_text()
    assert "constant velocity" in capsys.readouterr().out


def test_rollout_command_writes_everything(tiny_run):
    from thrombojax.io.hdf5 import open_dataset

    data, run, root = tiny_run
    out = root / "ro"
    assert main(["rollout", "--run", str(run), "--dataset", str(data), "--out", str(out),
                 "--sim", "sim_0", "--skip", "5", "--nodes", "100"]) == 0
    rep = json.loads((out / "rollout.json").read_text())["simulations"]["sim_0"]
    assert rep["t0"] == 5 and rep["n_steps"] == 6 and rep["n_nodes"] == 100
    assert set(rep["curves"]) == {"mgn", "constant velocity", "ground truth"}
    # constant velocity has the known error of a constant acceleration: grows like k^2
    mse_cv = np.asarray(rep["curves"]["constant velocity"]["mse"])
    assert (np.diff(mse_cv) > 0).all()
    assert rep["summary"]["ground truth"]["max_fraction_outside"] == 0.0
    ro = open_dataset(out / "sim_0_rollout.h5")
    sim = ro[ro.names[0]]
    assert sim.positions.shape == (8, 100, 3)
    full = open_dataset(data)["sim_0"]
    idx = np.asarray(rep["node_index"])
    np.testing.assert_allclose(sim.positions[:2], full.positions[4:6, idx], atol=1e-5)
    vessel = sim.node_type == NodeType.VESSEL
    assert np.array_equal(sim.positions[:, vessel], np.repeat(sim.positions[:1, vessel], 8, 0))
    for f in ("sim_0_prediction.xdmf", "sim_0_truth.xdmf", "sim_0_error.png",
              "sim_0_metrics.png", "rollout.md"):
        assert (out / f).is_file(), f
    assert Image.open(out / "sim_0_rollout.gif").n_frames == 8
    assert main(["export", str(out / "sim_0_rollout.h5"), "--out", str(root / "ex"),
                 "--format", "vtu"]) == 0
    assert (root / "ex" / "sim_0_rollout.pvd").is_file()
    # physical times frame * dt everywhere: the rollout starts at frame t0 - 1 = 4
    assert _times(root / "ex" / "sim_0_rollout.pvd", "DataSet", "timestep") == \
        pytest.approx((4 + np.arange(8)) * 0.01)
    assert _times(out / "sim_0_prediction.xdmf", "Time", "Value") == \
        pytest.approx((4 + np.arange(8)) * 0.01)
    assert main(["export", str(data), "--out", str(root / "ex"), "--sim", "sim_0"]) == 0
    assert _times(root / "ex" / "sim_0.xdmf", "Time", "Value") == \
        pytest.approx(np.arange(12) * 0.01)
    assert Image.open(out / "sim_0_summary.png").size[0] > 600
    assert "Dataset length unit: vessel radius" in (out / "rollout.md").read_text()
    assert main(["rollout", "--run", str(run), "--dataset", str(data), "--out", str(out),
                 "--sim", "nope"]) == 2
    # a dataset in another length unit is refused, not scaled silently
    assert json.loads((run / "config.json").read_text())["units"] == "vessel radius"
    from thrombojax.io.hdf5 import write_dataset

    src = open_dataset(data)
    mm = write_dataset(root / "mm.h5", [src[n] for n in src.names], name="mm", source="t",
                       units="mm")
    assert main(["rollout", "--run", str(run), "--dataset", str(mm), "--out", str(out)]) == 2
