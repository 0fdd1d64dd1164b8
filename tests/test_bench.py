"""bench: every model times a rollout on CPU; JSON + markdown carry device, versions, speed-ups."""

from __future__ import annotations

import json

import numpy as np

from thrombojax.bench import STUDY_CASES, synthetic_cloud
from thrombojax.cli import main
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
    assert main(["bench", "--models", ",".join(models), "--cases", "bendvessel,clotentry",
                 "--tiny", "--nodes", "128", "--max-steps", "3", "--repeats", "1",
                 "--out", str(tmp_path), "--quiet"]) == 0
    res = json.loads((tmp_path / "bench.json").read_text())
    assert {"device", "jax", "flax", "date", "load_avg_1m"} <= set(res["environment"])
    assert "no trained weights" in res["note"]
    assert [(r["model"], r["case"]) for r in res["results"]] == [
        (m, c) for m in models for c in ("bendvessel", "clotentry")]
    for r in res["results"]:
        case = STUDY_CASES[r["case"]]
        assert r["n_nodes"] == 128 and r["timed_steps"] == 3 and r["extrapolated"]
        assert r["compile_s"] > 0 and r["rollout_s"] > 0 and r["finite"] and not r["overflow"]
        assert np.isclose(r["full_length_s"], r["per_step_s"] * case.full_frames)
        assert np.isclose(r["speedup_vs_abaqus"], case.abaqus_s / r["full_length_s"])
    table = (tmp_path / "bench.md").read_text()
    assert "vs Abaqus" in table and "device" in table
    assert "mgn" in capsys.readouterr().out
    assert main(["bench", "--cases", "nope", "--quiet"]) == 2
