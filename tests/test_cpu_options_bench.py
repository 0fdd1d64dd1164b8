"""``benchmarks/cpu_options.py`` and ``benchmarks/flop_bound.py``: tiny runs on the CPU, their
rows, refusal to overwrite."""

from __future__ import annotations

import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import cpu_options  # noqa: E402
import flop_bound  # noqa: E402


def test_tiny_run_times_both_variants_and_refuses_to_overwrite(tmp_path):
    md = tmp_path / "opts.md"
    argv = ["--tiny", "--models", "mgn", "--sizes", "64", "--rounds", "2", "--calls", "1",
            "--out", str(md)]
    cpu_options.main(argv)
    text = md.read_text()
    rows = [line.split(" | ") for line in text.splitlines() if line.startswith("| mgn |")]
    assert [(r[1], r[2]) for r in rows] == [("step", "64"), ("train", "64")]
    for r in rows:
        ratio = float(r[5].split(" ")[0])
        default_ms, ours_ms = (float(r[i].split(" ")[0]) for i in (3, 4))
        assert ratio == pytest.approx(ours_ms / default_ms, rel=0.02, abs=0.01)
        assert float(r[6]) < 1e-4  # same results under both option sets
    assert "xla_cpu_experimental_ynn_fusion_type" in text and "# device: cpu" in text
    assert "no YNNPACK ms median" in text
    with pytest.raises(SystemExit):
        cpu_options.main(argv)  # exists: refused without --force
    assert md.read_text() == text


def test_flop_bound_tiny_run(tmp_path):
    md = tmp_path / "bound.md"
    flop_bound.main(["--tiny", "--sizes", "64", "--calls", "2", "--out", str(md)])
    row = next(line for line in md.read_text().splitlines() if line.startswith("| mgn |"))
    cells = row.strip("| ").split(" | ")
    gflop, ms, rate = float(cells[2]), float(cells[3]), float(cells[4])
    assert gflop > 0 and ms > 0 and rate == pytest.approx(gflop / ms * 1e3, rel=0.05, abs=1)
    floor, ratio = float(cells[6]), float(cells[7])
    assert ratio == pytest.approx(ms / floor, rel=0.05, abs=0.01)
    with pytest.raises(SystemExit):
        flop_bound.main(["--tiny", "--sizes", "64", "--out", str(md)])


def test_gif_bench_times_both_writers_and_finds_the_same_gif(tmp_path):
    import gif

    md = tmp_path / "gif.md"
    assert gif.main(["--frames", "3", "--clot", "12", "--wall", "20", "--rounds", "2",
                     "--out", str(md)]) == 0
    text = md.read_text()
    rows = {line.split(" | ")[0][2:]: line for line in text.splitlines()
            if line.startswith(("| thrombojax |", "| matplotlib |"))}
    assert set(rows) == {"thrombojax", "matplotlib"}
    assert "byte-identical: True" in text and "# matplotlib:" in text
    with pytest.raises(SystemExit):
        gif.main(["--frames", "3", "--clot", "12", "--wall", "20", "--out", str(md)])
