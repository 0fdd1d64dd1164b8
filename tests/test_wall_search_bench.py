"""``benchmarks/wall_search.py``: a small run on the CPU (both paths of the pruned search), its
rows and report, refusal to overwrite."""

from __future__ import annotations

import json
import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import wall_search  # noqa: E402

from thrombojax.graph import wall_nodes  # noqa: E402


def test_small_run_checks_both_searches_equal_and_refuses_to_overwrite(tmp_path):
    out, md = tmp_path / "ws.json", tmp_path / "ws.md"
    argv = ["--nodes", "200", "1600", "--batch", "1", "--repeats", "1", "--out", str(out),
            "--md", str(md)]
    assert wall_search.main(argv) == 0
    got = json.loads(out.read_text())
    rows = got["functions"]
    assert len(rows) == 2 * 2 * 2 * 2  # sizes x numberings x searches x variants
    assert {(r["what"], r["variant"]) for r in rows} == {
        (w, v) for w in ("wall_patches", "nearest_vessel_node") for v in ("before", "after")}
    assert all(r["equal"] for r in rows if r["variant"] == "after")
    assert all(r["ms"] > 0 for r in rows) and got["training"] is None
    # the module's own calls are back after the run
    assert wall_nodes.smallest_first is wall_search.VARIANTS["after"][0]
    assert wall_nodes.first_min is wall_search.VARIANTS["after"][1]
    text = md.read_text()
    assert "| wall_patches | 1600 | along | 1 |" in text and got["environment"]["device"] in text
    with pytest.raises(SystemExit):
        wall_search.main(argv)  # both files exist: refused, nothing rewritten
    assert json.loads(out.read_text()) == got
    with pytest.raises(SystemExit):
        wall_search.main(["--dataset", "x.h5"])  # --config missing
