"""`make demo`'s script end to end at its tiny size: every stage runs and writes what it lists."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_tiny_demo_runs_every_stage(tmp_path):
    out = tmp_path / "demo"
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, str(ROOT / "experiments" / "demo.py"), "--tiny",
                           "--quiet", "--out", str(out)], capture_output=True, text=True,
                          env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "constant velocity" in proc.stdout and "== in plain words" in proc.stdout
    for rel in ("run_mgn/config.json", "run_mgn/loss.png", "evaluate/evaluate.md",
                "rollout/rollout.md", "bench/bench.md"):
        assert (out / rel).is_file(), rel
    assert list((out / "rollout").glob("*_summary.png"))
