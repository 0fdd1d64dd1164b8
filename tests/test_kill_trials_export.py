"""kill -9 trials of ``thrombojax export`` (issue 14): 20 random kill times, every XDMF and its
HDF5 companion at a target path opens, the input dataset is unchanged, no temporary is left
after the next run. See ``tests/kill_trials.py``."""

from __future__ import annotations

import pytest
from kill_trials import TRIALS, run_kill_trials, tiny_dataset

pytestmark = pytest.mark.slow_safety


def test_kill_export_20_trials(tmp_path):
    data = tiny_dataset(tmp_path / "bv.h5")
    out = tmp_path / "ex"
    argv = ["export", str(data), "--out", str(out), "--force", "--quiet"]
    report = run_kill_trials(argv, out, [data], seed=14_04)
    assert len(report.kill_times) == TRIALS
    assert report.killed >= TRIALS // 2, report  # most trials kill a running command
    assert len(list(out.glob("*.xdmf"))) == 3
