"""kill -9 trials of ``thrombojax generate`` (issue 14): 20 random kill times, every file at a
target path opens, a bystander dataset in the same folder is unchanged, no temporary is left
after the next run. See ``tests/kill_trials.py``."""

from __future__ import annotations

import shutil

import pytest
from kill_trials import TRIALS, run_kill_trials

from thrombojax.cli import main

pytestmark = pytest.mark.slow_safety


def test_kill_generate_20_trials(tmp_path):
    out = tmp_path / "gen"
    out.mkdir()
    seed_data = tmp_path / "seed.h5"
    assert main(["generate", "bendvessel-tiny", "--out", str(seed_data), "--sims", "1",
                 "--quiet"]) == 0
    bystander = out / "precious.h5"  # a user's dataset beside the target
    shutil.copy(seed_data, bystander)
    argv = ["generate", "bendvessel-tiny", "--out", str(out / "g.h5"), "--sims", "1", "--plot",
            "--force", "--quiet"]
    report = run_kill_trials(argv, out, [bystander], seed=14_01)
    assert len(report.kill_times) == TRIALS
    assert report.killed >= TRIALS // 2, report  # most trials kill a running command
    assert (out / "g.h5").is_file() and (out / "g.png").is_file()
