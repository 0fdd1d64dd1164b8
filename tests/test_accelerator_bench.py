"""``benchmarks/accelerator.py``: a tiny run on the CPU, its report, refusal to overwrite, merge."""

from __future__ import annotations

import json
import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import accelerator  # noqa: E402


def _run(out, *extra):
    return accelerator.main(["--tiny", "--models", "mgn", "--cases", "step", "train",
                             "--sizes", "64", "--repeats", "2", "--precisions", "F32_F32_F32",
                             "--step-precisions", "TF32_TF32_F32", "--out", str(out), *extra])


def test_tiny_run_writes_report_records_errors_and_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "acc.md"
    assert _run(out) == 0
    got = json.loads(out.with_suffix(".json").read_text())
    rows = {(r["case"], r["precision"]): r for r in got["rows"]}
    f32 = rows[("step", "F32_F32_F32")]
    assert f32["per_step_ms"] > 0 and f32["dev"] == 0.0 and f32["params"] > 0
    assert rows[("train", "F32_F32_F32")]["median_ms"] > 0
    text = out.read_text()
    assert got["env"]["device"] in text and "| mgn | F32_F32_F32 |" in text
    # TF32 products do not exist on the CPU: recorded as an error, not dropped
    if got["env"]["device"].startswith("cpu"):
        assert "error" in rows[("step", "TF32_TF32_F32")]
        assert "| mgn | TF32_TF32_F32 | error | error |" in text
    capsys.readouterr()
    with pytest.raises(SystemExit):
        _run(out)
    assert "acc.md: report already exists; pass --force to replace it" in capsys.readouterr().err
    out.unlink()  # the .json beside it still holds timings: refused too
    with pytest.raises(SystemExit):
        _run(out)
    assert "acc.json: report already exists" in capsys.readouterr().err


def test_merge_joins_runs_into_one_table(tmp_path):
    env = {"device": "gpu:X", "jax": "j", "jaxlib": "j", "flax": "f", "python": "3",
           "cpu_count": 1, "load_avg_1_5_15": [0, 0, 0], "date": "d", "command": "c",
           "rollout_steps": 40}
    row = {"model": "mgn", "case": "step", "nodes": 2048, "per_step_ms": 2.0}
    for i, prec in enumerate(["F32_F32_F32", "BF16_BF16_F32"]):
        (tmp_path / f"{i}.json").write_text(json.dumps(
            {"env": {**env, "command": f"run{i}"}, "rows": [{**row, "precision": prec,
                                                             "per_step_ms": 2.0 + i}]}))
    out = tmp_path / "merged.md"
    assert accelerator.main(["--merge", str(tmp_path / "0.json"), str(tmp_path / "1.json"),
                             "--out", str(out)]) == 0
    text = out.read_text()
    assert "run 1:" in text and "`run1`" in text
    assert "| mgn | F32_F32_F32 | 2.00 |" in text and "| mgn | BF16_BF16_F32 | 3.00 |" in text
    assert [r["run"] for r in json.loads(out.with_suffix(".json").read_text())["rows"]] == [1, 2]
    with pytest.raises(SystemExit):  # a merged run's own JSON is never the target, even forced
        accelerator.main(["--merge", str(tmp_path / "0.json"), "--out", str(tmp_path / "0.md"),
                          "--force"])
    assert (tmp_path / "0.json").read_text().startswith('{"env"')
