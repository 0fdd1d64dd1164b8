"""kill -9 trials of ``thrombojax rollout`` (issue 14): 20 random kill times; every HDF5, XDMF,
GIF, PNG and JSON at a target path opens, the run folder and dataset are unchanged, no
temporary is left after the next run. See ``tests/kill_trials.py``."""

from __future__ import annotations

import pytest
from kill_trials import TRIALS, run_kill_trials, tiny_dataset

from thrombojax.cli import main

pytestmark = pytest.mark.slow_safety


def test_kill_rollout_20_trials(tmp_path):
    data = tiny_dataset(tmp_path / "bv.h5")
    run = tmp_path / "run"
    assert main(["train", "--dataset", str(data), "--model", "mgn", "--out", str(run), "--tiny",
                 "--epochs", "1", "--warmup-epochs", "0", "--n-val", "1", "--quiet"]) == 0
    out = tmp_path / "ro"
    argv = ["rollout", "--run", str(run), "--dataset", str(data), "--out", str(out),
            "--steps", "3", "--force", "--quiet"]
    report = run_kill_trials(argv, out, [data, run], seed=14_03)
    assert len(report.kill_times) == TRIALS
    assert report.killed >= TRIALS // 2, report  # most trials kill a running command
    assert list(out.glob("*.gif")) and (out / "rollout.json").is_file()
