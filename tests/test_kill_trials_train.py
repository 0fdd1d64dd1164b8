"""kill -9 trials of ``thrombojax train`` (issue 14): 20 random kill times on a tiny model and
one epoch; config.json, metrics.jsonl and loss.png open, every checkpoint on disk loads, the
dataset and a user's file in the run folder are unchanged, no temporary is left after the next
run. See ``tests/kill_trials.py``."""

from __future__ import annotations

import pytest
from kill_trials import TRIALS, run_kill_trials, tiny_dataset

from thrombojax.train.state import latest_step, load_trained

pytestmark = pytest.mark.slow_safety


def checkpoints_load(run):
    for which in ("best", "last"):
        if latest_step(run / "checkpoints" / which) is not None:
            load_trained(run, which=which)


def test_kill_train_20_trials(tmp_path):
    data = tiny_dataset(tmp_path / "bv.h5")
    run = tmp_path / "run"
    run.mkdir()
    notes = run / "notes.txt"  # not a run file: train --force must leave it alone
    notes.write_text("my notes\n")
    argv = ["train", "--dataset", str(data), "--model", "mgn", "--out", str(run), "--tiny",
            "--epochs", "1", "--warmup-epochs", "0", "--n-val", "1", "--force", "--quiet"]
    report = run_kill_trials(argv, run, [data, notes], seed=14_02, check=checkpoints_load)
    assert len(report.kill_times) == TRIALS
    assert report.killed >= TRIALS // 2, report  # most trials kill a running command
    checkpoints_load(run)
    assert latest_step(run / "checkpoints" / "last") is not None
