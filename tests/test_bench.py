"""bench: every model times a rollout on CPU; JSON + markdown carry device, versions, speed-ups."""

from __future__ import annotations

import json

import numpy as np

from thrombojax.cli import main
from thrombojax.eval.bench import STUDY_CASES, bench, synthetic_cloud
from thrombojax.models.registry import MODEL_NAMES
from thrombojax.types import NodeType


def test_synthetic_cloud_shapes():
    x_prev, x_cur, node_type = synthetic_cloud(977, seed=1)
    assert x_cur.shape == (977, 3) and np.abs(x_cur).max() <= 1.0
    clot = node_type == NodeType.CLOT
    assert 0.25 < clot.mean() < 0.35
    assert np.array_equal(x_prev[~clot], x_cur[~clot]) and not np.allclose(x_prev[clot],
                                                                           x_cur[clot])


def test_bench_cli_all_models(tmp_path, capsys):
    models = [m for m in ("mgn", "transolver", "erwin") if m in MODEL_NAMES]
    assert main(["bench", "--models", ",".join(models), "--cases", "bendvessel",
                 "--tiny", "--nodes", "128", "--max-steps", "3", "--repeats", "1",
                 "--out", str(tmp_path), "--quiet"]) == 0
    res = json.loads((tmp_path / "bench.json").read_text())
    env = set(res["environment"])
    assert {"device", "jax", "flax", "date", "load_avg_1_5_15", "command", "allocator",
            "xla_options"} <= env
    assert "no trained weights" in res["note"]
    assert [(r["model"], r["case"]) for r in res["results"]] == [
        (m, "bendvessel") for m in models]
    for r in res["results"]:
        case = STUDY_CASES[r["case"]]
        assert r["n_nodes"] == 128 and r["timed_steps"] == 3 and r["extrapolated"]
        assert r["compile_s"] > 0 and r["rollout_s"] > 0 and r["finite"]
        assert r["graph"] == "dense" and r["grid"] is None  # small clouds: no cell grid
        assert np.isclose(r["full_length_s"], r["per_step_s"] * case.full_frames)
        assert np.isclose(r["speedup_vs_abaqus"], case.abaqus_s / r["full_length_s"])
    table = (tmp_path / "bench.md").read_text()
    assert "vs Abaqus" in table and "device" in table
    assert "mgn" in capsys.readouterr().out
    assert main(["bench", "--cases", "nope", "--quiet"]) == 2


def test_bench_cases_and_solver_dataset(tmp_path):
    from thrombojax.io.hdf5 import Simulation, write_dataset

    _, x, node_type = synthetic_cloud(200, seed=0)
    sims = [Simulation(name=f"s{i}", positions=np.repeat(x[None], 3, 0),
                       node_type=node_type.astype(np.int8), attrs={"solver_wall_time_s": 4.0 + i})
            for i in range(2)]
    data = write_dataset(tmp_path / "bend.h5", sims, name="bend", source="test", kind="bendvessel")
    res = bench(("constant_velocity",), ("bendvessel", "clotentry"), n_nodes=64, max_steps=2,
                repeats=1, dataset=str(data), solver_datasets=(str(data),), progress=False)
    bend, clot = res["results"]
    assert bend["solver_s"] == 4.5 and "solver_s" not in clot  # its kind attribute: BendVessel
    assert np.isclose(bend["speedup_vs_solver"], 4.5 / bend["full_length_s"])
    assert bend["positions"].endswith(":s0") and clot["n_steps"] == 160
