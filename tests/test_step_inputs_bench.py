"""``benchmarks/step_inputs.py``: a tiny run on the CPU, its rows and report, refusal to
overwrite."""

from __future__ import annotations

import json
import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import step_inputs  # noqa: E402


def test_tiny_run_times_every_step_and_part_and_refuses_to_overwrite(tmp_path):
    out, md = tmp_path / "si.json", tmp_path / "si.md"
    argv = ["--nodes", "64", "--repeats", "1", "--size", "tiny", "--out", str(out), "--md", str(md)]
    assert step_inputs.main(argv) == 0
    got = json.loads(out.read_text())
    rows = {r["what"]: r for r in got["rows"]}
    steps = [f"step {label}" for label, _ in step_inputs.STEPS]
    assert set(rows) == {*steps, "step + prior, rollout context",
                         "rollout + prior, search every step", "rollout + prior, rollout context",
                         "model",
                         "wall_node_features", "local_wall_plane", "vessel_axis",
                         "vessel_axis, rollout context"}
    assert all(r["nodes"] == 64 and r["ms"] > 0 for r in rows.values())
    assert rows["step plain"]["ratio"] == 1.0
    assert rows["step + prior"]["ratio"] == round(
        rows["step + prior"]["ms"] / rows["step plain"]["ms"], 2)
    text = md.read_text()
    assert got["environment"]["device"] in text and "| step + axis | 64 |" in text
    with pytest.raises(SystemExit):
        step_inputs.main(argv)  # both files exist: refused, nothing rewritten
    assert json.loads(out.read_text()) == got
    assert step_inputs.main([*argv, "--force"]) == 0  # --force replaces both
    with pytest.raises(SystemExit):  # one file for both reports: refused even forced
        step_inputs.main([*argv[:-2], "--md", str(out), "--force"])
