"""Shared helpers of the experiment-runner tests (smoke-scale runs and the study's numbers)."""

from thrombojax import study
from thrombojax.experiments.runner import run_experiment
from thrombojax.experiments.spec import find_experiment


def run_smoke(name, tmp_path, data_dir):
    """Run experiment ``name`` at smoke scale into ``tmp_path/name``; every run must finish.

    Returns ``(out_dir, table_markdown, result)``.
    """
    out = tmp_path / name
    res = run_experiment(find_experiment(name), "smoke", out, data_dir=data_dir,
                         log=lambda m: None)
    assert res["finished"] == res["runs"] and res["report"] is not None
    return out, (out / "table.md").read_text(), res


def study_pm(kind, model):
    """The study's published test MSE of ``model`` on ``kind`` as the tables print it."""
    m, s = study.TEST_MSE[kind][model]
    return f"{m:.4g} ± {s:.2g}"
