"""The sweeps (BaryCentricSampling ratio, node count, generalisation), the rollouts and the
stability ladder at their smoke scale, from nothing to the table and the plots."""

import json

import numpy as np
import pytest
from experiment_helpers import run_smoke, study_pm

from thrombojax.experiments.data import ensure_dataset
from thrombojax.experiments.spec import find_experiment

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("expdata")
    for preset in ("bendvessel-tiny", "clotentry-tiny"):
        ensure_dataset(preset, folder)
    return folder


@pytest.mark.parametrize("name", ["bary_ratio_sweep", "node_count_sweep", "generalisation"])
def test_sweeps(name, tmp_path, data_dir):
    out, table, _ = run_smoke(name, tmp_path, data_dir)
    exp = find_experiment(name)
    values = exp.scale("smoke").values
    rows = [ln for ln in table.splitlines() if ln.startswith("| bendvessel-tiny |")
            or ln.startswith("| clotentry-tiny |")]
    assert len(rows) == len(values)
    kind = "clotentry" if name == "node_count_sweep" else "bendvessel"
    assert all(study_pm(kind, "mgn") in r for r in rows)
    assert (out / "sweep.png").stat().st_size > 0
    if name == "generalisation":  # tested on the largest rotation, trained up to the value
        for v in values:
            found = next((out / "runs").glob(f"*train_deg-{v}__s0/result.json"))
            res = json.loads(found.read_text())
            split = json.loads((out / "runs" / res["key"] / "config.json").read_text())["split"]
            assert split["test"] == ["bendvessel-tiny_003"]
            assert res["metrics"]["test_rotation_deg"] == 30.0
            assert len(split["train"]) == v // 10 + 1


def test_rollouts_and_ladder(tmp_path, data_dir):
    out, table, _ = run_smoke("rollouts", tmp_path, data_dir)
    for model in ("mgn", "transolver"):
        res = json.loads((out / "runs" / f"bendvessel-tiny__{model}__s0" / "result.json")
                         .read_text())["metrics"]["rollout"]
        curve = np.array(res["mse_per_step_r2"])
        assert curve.shape == (7,) and np.all(np.isfinite(curve))  # 8 frames, skip 1
        assert f"{res['mse_full_r2']:.4g}" in table
    assert (out / "rollout_error.png").stat().st_size > 0
    out, table, _ = run_smoke("stability_ladder", tmp_path, data_dir)
    assert "| baseline |" in table and "| kstep |" in table and "| kstep + guards |" in table
    assert (out / "runs" / "bendvessel-tiny__mgn__rung-kstep__s0" / "rollout_guards").is_dir()
    cfg = json.loads((out / "runs" / "bendvessel-tiny__mgn__rung-kstep__s0" / "config.json")
                     .read_text())["train"]
    assert cfg["rollout_steps"] == 2 and cfg["pushforward_steps"] == 1


