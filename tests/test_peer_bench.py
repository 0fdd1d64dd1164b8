"""``benchmarks/peer.py`` (the PyTorch peer comparison of issue 17) without the peer stack.

The test environment has no torch: the script must exit 0 at once, say what it skipped and how
to install the peers, and never import torch or start a worker. Its plan and report helpers
are checked on made-up timings (no model is run).
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(ROOT, "benchmarks", "peer.py")
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import peer  # noqa: E402
import peer_report  # noqa: E402


def _no_torch() -> bool:
    import importlib.util
    return importlib.util.find_spec("torch") is None


@pytest.mark.skipif(not _no_torch(), reason="torch is installed here")
def test_exits_zero_and_says_torch_is_missing():
    out = subprocess.run([sys.executable, SCRIPT, "--quick"], capture_output=True, text=True,
                         timeout=60, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert "skipped: torch not installed" in out.stdout
    assert "pip wheel --no-build-isolation --no-deps torch_scatter torch_cluster" in out.stdout
    assert "--erwin-src" in out.stdout


def test_help_explains_the_flags():
    out = subprocess.run([sys.executable, SCRIPT, "--help"], capture_output=True, text=True,
                         timeout=60, cwd=ROOT)
    assert out.returncode == 0
    for flag in ("--rounds", "--steps", "--sizes", "--models", "--cases", "--out",
                 "--erwin-src", "--quick"):
        assert flag in out.stdout


def test_missing_erwin_source_skips_only_erwin(tmp_path):
    lacking = peer.missing_packages(["mgn", "erwin"], str(tmp_path))
    assert any(str(tmp_path) in what for what in lacking["erwin"])
    if _no_torch():
        assert "torch" in lacking["mgn"]


def test_plan_groups_cases_by_model_and_size():
    args = peer.parse(["--models", "mgn", "erwin", "--sizes", "977", "2048"])
    groups = peer.plan(args)
    assert [["mgn", "step", 977], ["mgn", "rollout", 977], ["mgn", "train", 977]] in groups
    assert [["mgn", "forward", 27000]] in groups
    assert not any(c[0] == "erwin" and c[1] == "forward" for g in groups for c in g)


def test_report_ratios_targets_and_mismatch():
    args = peer.parse(["--models", "mgn", "--sizes", "2048", "--cases", "step", "train"])
    sides = list(peer.SIDES)
    ms = {"thrombojax": 30.0, "peer default": 100.0, "peer tcmalloc": 60.0}
    params = {"thrombojax": 10, "peer default": 11, "peer tcmalloc": 11}
    keys = ["mgn|step|2048", "mgn|train|2048"]
    result = {
        "ready": {s: {"info": {k: {"params": params[s]} for k in keys}} for s in sides},
        "rounds": {s: [{"key": k, "ms": ms[s], "faults_per_step": 0.0} for k in keys]
                   for s in sides},
        "load": [1.0, 1.0, 1.0],
    }
    env = {"load_avg_start": [1.0, 1.0, 1.0], "load_avg_end": [1.0, 1.0, 1.0]}
    text = "\n".join(peer_report.tables([result], sides, args, env))
    assert "| 0.30 | 0.50 |" in text  # 30 / 100 and 30 / 60
    assert "met" in text  # train: 0.30 <= 0.5 and 0.50 <= 0.6
    assert "MISSED" in text  # step at 2,048: 0.50 > 0.33 (same allocator)
    assert "MISMATCH" in text
