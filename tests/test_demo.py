"""`make demo`'s script end to end at its tiny size: every stage runs and writes what it lists."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)

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


def test_demo_recipe_option_reaches_the_training(tmp_path, monkeypatch, capsys):
    """`--recipe NAME` trains the demo with that recipe; without it, the default recipe of
    `thrombojax train`; an unknown name is refused by the parser, naming the choices."""
    import importlib.util

    import pytest

    from thrombojax.train.recipes import DEFAULT_RECIPE

    spec = importlib.util.spec_from_file_location("demo_script", ROOT / "experiments" / "demo.py")
    demo = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "demo_script", demo)  # dataclasses look their module up
    spec.loader.exec_module(demo)
    seen = []
    monkeypatch.setattr(demo, "run_demo", lambda out, config, progress: seen.append(config))
    assert demo.main(["--out", str(tmp_path / "a"), "--recipe", "robust", "--quiet"]) == 0
    assert demo.main(["--out", str(tmp_path / "b"), "--quiet"]) == 0
    assert [c.recipe for c in seen] == ["robust", DEFAULT_RECIPE]
    with pytest.raises(SystemExit):
        demo.main(["--recipe", "fast"])
    assert "invalid choice: 'fast'" in capsys.readouterr().err
