"""The 5-seed table, the timing and the search at their smoke scale, from nothing to the table.

(rotation_sweep runs in tests/test_experiments.py with the resume test, the other sweeps, the
rollouts and the ladder in tests/test_experiments_sweeps.py.) The dataset is generated once
per module into a shared data folder, as ``--data-dir`` does.
"""

import json

import pytest
from experiment_helpers import run_smoke, study_pm

from thrombojax import study
from thrombojax.cli import main
from thrombojax.experiments.data import ensure_dataset
from thrombojax.train.config import TrainConfig, load_config_file

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("expdata")
    ensure_dataset("bendvessel-tiny", folder)
    return folder


def test_test_mse_table_beside_the_study(tmp_path, data_dir, capsys):
    out = tmp_path / "test_mse"
    assert main(["experiment", "run", "test_mse", "--scale", "smoke", "--out", str(out),
                 "--data-dir", str(data_dir), "--quiet"]) == 0
    printed = capsys.readouterr().out
    table = (out / "table.md").read_text()
    for kind, preset in (("bendvessel", "bendvessel-tiny"),):
        for model in ("mgn", "transolver", "erwin"):
            row = next(ln for ln in table.splitlines()
                       if ln.startswith(f"| {preset} | {model} |"))
            assert study_pm(kind, model) in row
            m = json.loads((out / "runs" / f"{preset}__{model}__s0" / "result.json")
                           .read_text())["metrics"]
            # scaled, physical (vessel radii squared) and against constant velocity
            for value in (m["mse"], m["mse_r2"], m["mse"] / m["cv_mse"]):
                assert f"| {value:.4g} |" in row
    assert "ours / CV" in table and "(r^2)" in table
    assert (out / "test_mse.png").stat().st_size > 0
    assert "3 of 3 done" in printed


def test_timing(tmp_path, data_dir):
    out, table, _ = run_smoke("rollout_timing", tmp_path, data_dir)
    for model in ("mgn", "transolver"):
        row = next(ln for ln in table.splitlines() if ln.startswith(f"| {model} | bendvessel"))
        assert f"| {study.ROLLOUT_TIME_S['bendvessel'][model]:.4g} |" in row
        assert f"| {study.DATASETS['bendvessel'].abaqus_s:.4g} |" in row
        ratio = study.DATASETS["bendvessel"].abaqus_s / study.ROLLOUT_TIME_S["bendvessel"][model]
        assert row.rstrip().endswith(f"| x{ratio:.0f} |")  # the study's speed-up beside ours
        bench = json.loads((out / "runs" / model / "result.json").read_text())["metrics"]
        assert bench["bench"][0]["solver_s"] > 0  # our solver's time from the dataset


def test_search_resumes_after_a_kill_and_exports_a_train_config(tmp_path, data_dir,
                                                                monkeypatch):
    pytest.importorskip("optuna")
    from thrombojax.experiments import search

    out = tmp_path / "search"
    args = ["experiment", "run", "hyperparameter_search", "--scale", "smoke", "--out",
            str(out), "--data-dir", str(data_dir), "--quiet"]
    real = search.train_run

    def killed_in_trial_1(run, cfg, folder, *a, **kw):
        if folder.name == "trial_0001":
            raise KeyboardInterrupt  # the process is killed during the second trial
        return real(run, cfg, folder, *a, **kw)

    monkeypatch.setattr(search, "train_run", killed_in_trial_1)
    assert main(args) == 130
    first = out / "trials" / "trial_0000" / "metrics.jsonl"
    stamp = first.stat().st_mtime_ns
    monkeypatch.setattr(search, "train_run", real)
    assert main(args) == 0  # resumes: trial 0 kept, one more trial finishes the search
    assert first.stat().st_mtime_ns == stamp
    assert sorted(p.name for p in (out / "trials").iterdir()) == ["trial_0000", "trial_0002"]
    assert main(args) == 0  # finished: no new trial
    assert len(list((out / "trials").iterdir())) == 2
    best = load_config_file(out / "best_config.json")
    assert isinstance(best, TrainConfig) and best.tiny
    assert (out / "search.db").is_file() and (out / "history.png").is_file()
    assert "study's choice" in (out / "table.md").read_text()
    trained = main(["train", "--config", str(out / "best_config.json"), "--model", "mgn",
                    "--dataset", str(data_dir / "bendvessel-tiny.h5"), "--out",
                    str(tmp_path / "best_run"), "--epochs", "1", "--quiet"])
    assert trained == 0
