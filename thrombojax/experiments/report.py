"""An experiment's report: seeds aggregated (mean +- std), the study's numbers beside ours.

:func:`write_report` reads every run's ``result.json`` and writes ``DIR/table.md`` (the table,
how to read it, the device, versions, date and load of ``thrombojax.eval.tables.environment``),
``DIR/results.json`` (every aggregate) and the plots:

* ``test_mse.png`` (the seeds table): test MSE per model and dataset, one-std error bars,
  every seed a dot, constant velocity dashed;
* ``sweep.png`` (a sweep or a generalisation): test MSE against the swept value, error bars one
  std over seeds, one line per model and dataset, constant velocity dashed;
* ``rollout_error.png`` (rollouts and the ladder): MSE per rollout step per model, shaded one
  std over seeds, constant velocity dashed.

Test MSE is given in scaled coordinates (the study's metric), in vessel radii squared and as a
ratio to constant velocity. The study's numbers are those of ``thrombojax/study.py``: the
5-seed test MSE (``TEST_MSE``) and the rollout times (``ROLLOUT_TIME_S``, Abaqus times in
``DATASETS``); the study published no per-value sweep numbers, so sweeps show its test MSE at
the setting it kept.
"""

from __future__ import annotations

import json
import math
import pathlib
from collections.abc import Sequence

import matplotlib.pyplot as plt
import numpy as np

from thrombojax import study
from thrombojax.eval.tables import environment, markdown_table
from thrombojax.experiments.spec import Experiment
from thrombojax.io.outputs import atomic_path, atomic_write_text
from thrombojax.sim.presets import get_preset
from thrombojax.train.config import parse_angle

__all__ = ["mean_std", "aggregate", "report_table", "write_report"]


def mean_std(values: Sequence[float]) -> tuple[float, float]:
    """Mean and sample standard deviation (ddof 1; 0 for a single value)."""
    a = np.asarray(values, np.float64)
    return float(a.mean()), float(a.std(ddof=1)) if a.size > 1 else 0.0


def _pm(values: Sequence[float]) -> str:
    m, s = mean_std(values)
    return f"{m:.4g} ± {s:.2g}" if len(values) > 1 else f"{m:.4g}"


def _times(x: float) -> str:
    return f"x{x:.0f}" if x >= 10 else f"x{x:.2g}"


def _study_mse(dataset: str, model: str) -> str:
    kind = get_preset(dataset).study
    if model not in study.TEST_MSE.get(kind, {}):
        return "-"
    m, s = study.TEST_MSE[kind][model]
    return f"{m:.4g} ± {s:.2g}"


def aggregate(results: list[dict]) -> dict[tuple, list[dict]]:
    """Results grouped by (dataset, model, value label), seeds in order."""
    groups: dict[tuple, list[dict]] = {}
    for r in sorted(results, key=lambda r: r["seed"]):
        groups.setdefault((r["dataset"], r["model"], r["label"]), []).append(r)
    return groups


def _x(label: str) -> float:
    try:
        return parse_angle(label)
    except Exception:  # noqa: BLE001 - a non-numeric label is plotted by position
        return math.nan


def report_table(experiment: Experiment, results: list[dict]) -> tuple[str, str]:
    """``(markdown table, note)`` of an experiment's finished runs."""
    groups, kind = aggregate(results), experiment.kind
    rows = []
    if kind == "timing":
        for r in results:
            for b in r["metrics"]["bench"]:
                ref = study.ROLLOUT_TIME_S.get(b["case"], {}).get(b["model"])
                rows.append([b["model"], b["case"], b["n_nodes"], b["config"],
                             b["full_length_s"], "-" if ref is None else ref, b["abaqus_s"],
                             b.get("solver_s", "n/a"), _times(b["speedup_vs_abaqus"]),
                             "-" if ref is None else _times(b["abaqus_s"] / ref)])
        header = ["model", "case", "nodes", "config", "ours: full-length rollout s",
                  "study (A100) s", "Abaqus s", "our solver s", "ours vs Abaqus",
                  "study vs Abaqus"]
        note = ("Full-length time = per-step time x all frames (thrombojax/eval/bench.py); the "
                "study's times are on one A100, ours on the device listed below.")
        return markdown_table(header, rows), note
    for (dataset, model, label), runs in groups.items():
        m = [r["metrics"] for r in runs]
        n = len(runs)
        if kind in ("sweep", "seeds", "generalisation"):
            row = [dataset, model] + ([label] if kind != "seeds" else [])
            if kind == "generalisation":
                row.append(f"{m[0]['test_rotation_deg']:g}")
            row += [_pm([x["mse"] for x in m]), _pm([x["cv_mse"] for x in m]),
                    _pm([x["mse_r2"] for x in m]), _pm([x["mse"] / x["cv_mse"] for x in m]), n,
                    _study_mse(dataset, model)]
            rows.append(row)
        elif kind == "rollout":
            rows.append([dataset, model, _pm([x["mse"] for x in m]),
                         _pm([x["rollout"]["mse10_r2"] for x in m]),
                         _pm([x["rollout"]["mse_full_r2"] for x in m]),
                         _pm([x["rollout"]["cv_mse_full_r2"] for x in m]), n,
                         _study_mse(dataset, model)])
        elif kind == "ladder":
            for name, ro in m[0]["rollouts"].items():
                rows.append([label + (" + guards" if ro["guards"] else ""), dataset, model,
                             _pm([x["mse"] / x["cv_mse"] for x in m]),
                             _pm([x["rollouts"][name]["mse10_r2"] for x in m]),
                             _pm([x["rollouts"][name]["mse_full_r2"] for x in m]),
                             _pm([x["rollouts"][name]["mse_full_r2"]
                                  / x["rollouts"][name]["cv_mse_full_r2"] for x in m]), n])
    ours = ["ours: test MSE", "constant velocity MSE", "ours: test MSE (r^2)", "ours / CV"]
    headers = {
        "sweep": ["dataset", "model", experiment.sweep or "value", *ours, "seeds",
                  "study: test MSE (its setting)"],
        "seeds": ["dataset", "model", *ours, "seeds", "study: test MSE"],
        "generalisation": ["dataset", "model", "trained on rotations <= (deg)",
                           "test rotation (deg)", *ours, "seeds",
                           "study: test MSE (in distribution)"],
        "rollout": ["dataset", "model", "single-step test MSE", "rollout MSE@10 (r^2)",
                    "rollout MSE full (r^2)", "CV rollout MSE full (r^2)", "seeds",
                    "study: single-step test MSE"],
        "ladder": ["rung", "dataset", "model", "single-step MSE / CV", "MSE@10 (r^2)",
                   "MSE full (r^2)", "MSE full / CV", "seeds"],
    }
    notes = {
        "ladder": "The stability ladder is this project's, not the study's: no study numbers.",
        "rollout": "The study published no rollout error numbers; its single-step test MSE is "
                   "shown. r: vessel radii.",
    }
    note = notes.get(kind, "Test MSE: one teacher-forced step, clot nodes, scaled [-1, 1] "
                           "coordinates (the study's metric); (r^2): the same in vessel radii "
                           "squared; ours / CV: against extrapolating the current velocity "
                           "(< 1 beats it). Mean ± sample std over seeds.")
    return markdown_table(headers[kind], rows), note


def _plot_sweep(experiment: Experiment, groups: dict, path: pathlib.Path) -> None:
    fig, ax = plt.subplots(figsize=(6, 4))
    lines: dict[tuple, list] = {}
    for (dataset, model, label), runs in groups.items():
        lines.setdefault((dataset, model), []).append((label, [r["metrics"]["mse"]
                                                                for r in runs]))
    for (dataset, model), pts in lines.items():
        xs = [_x(lb) for lb, _ in pts]
        if any(math.isnan(x) for x in xs):
            xs = list(range(len(pts)))
        stats = [mean_std(v) for _, v in pts]
        ax.errorbar(xs, [s[0] for s in stats], yerr=[s[1] for s in stats], marker="o",
                    capsize=3, label=f"{model} ({dataset})")
    for dataset, cvs in _cv_by_dataset(groups).items():
        ax.axhline(float(np.mean(cvs)), color="k", ls="--", lw=1,
                   label=f"constant velocity ({dataset})")
    _save_log_plot(fig, ax, path, experiment.title, experiment.sweep
                   or "trained on rotations up to (deg)", "test MSE (scaled coordinates)", 8)


def _cv_by_dataset(groups: dict) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {}
    for (dataset, _, _), runs in groups.items():
        out.setdefault(dataset, []).extend(r["metrics"]["cv_mse"] for r in runs)
    return out


def _plot_seeds(experiment: Experiment, groups: dict, path: pathlib.Path) -> None:
    """Test MSE per model and dataset (mean, one-std error bar, every seed as a dot), with the
    constant-velocity MSE of the same test windows as a dashed line."""
    fig, ax = plt.subplots(figsize=(6, 4))
    keys = list(groups)
    for i, key in enumerate(keys):
        v = [r["metrics"]["mse"] for r in groups[key]]
        m, s = mean_std(v)
        ax.bar(i, m, yerr=s, capsize=4, color=f"C{i % 10}", alpha=0.7)
        ax.plot([i] * len(v), v, "k.", ms=4)
    cvs = _cv_by_dataset(groups)
    for dataset, values in cvs.items():
        ax.axhline(float(np.mean(values)), color="k", ls="--", lw=1,
                   label=f"constant velocity ({dataset})")
    ax.set_xticks(range(len(keys)), [f"{model}\n{dataset}" for dataset, model, _ in keys])
    _save_log_plot(fig, ax, path, experiment.title, "", "test MSE (scaled coordinates)", 8)


def _plot_rollouts(experiment: Experiment, groups: dict, path: pathlib.Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4))
    cv = None
    for (dataset, model, label), runs in groups.items():
        m = [r["metrics"] for r in runs]
        per_name = ({"rollout": [x["rollout"] for x in m]} if experiment.kind == "rollout"
                    else {n: [x["rollouts"][n] for x in m] for n in m[0]["rollouts"]})
        for name, ros in per_name.items():
            curves = np.array([ro["mse_per_step_r2"] for ro in ros])
            steps = np.arange(1, curves.shape[1] + 1)
            tag = f"{label} + guards" if name == "rollout_guards" else (label or model)
            mean, std = curves.mean(0), curves.std(0, ddof=1) if len(curves) > 1 else 0 * steps
            ax.plot(steps, mean, label=f"{tag} ({dataset})" if label else f"{model} ({dataset})")
            ax.fill_between(steps, np.maximum(mean - std, 1e-12), mean + std, alpha=0.2)
            cv = cv if cv is not None else (steps, np.mean([ro["cv_mse_per_step_r2"]
                                                            for ro in ros], axis=0))
    if cv is not None:
        ax.plot(*cv, "k--", label="constant velocity")
    _save_log_plot(fig, ax, path, experiment.title, "rollout step",
                   "MSE of clot nodes (vessel radii$^2$)", 7)


def _save_log_plot(fig, ax, path: pathlib.Path, title: str, xlabel: str, ylabel: str,
                   legend_size: int) -> None:
    """Log y axis, labels, title and legend; write the figure atomically and close it."""
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=legend_size)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)


def write_report(experiment: Experiment, scale: str, results: list[dict],
                 out: str | pathlib.Path, *, extra: str = "") -> dict:
    """Write ``table.md``, ``results.json`` and the plots of an experiment; returns paths and
    the table."""
    out = pathlib.Path(out)
    table, note = report_table(experiment, results)
    groups = aggregate(results)
    files = [out / "table.md", out / "results.json"]
    if experiment.kind in ("sweep", "generalisation"):
        _plot_sweep(experiment, groups, out / "sweep.png")
        files.append(out / "sweep.png")
    if experiment.kind == "seeds":
        _plot_seeds(experiment, groups, out / "test_mse.png")
        files.append(out / "test_mse.png")
    if experiment.kind in ("rollout", "ladder"):
        _plot_rollouts(experiment, groups, out / "rollout_error.png")
        files.append(out / "rollout_error.png")
    env = environment()
    notes = sorted({r["tensorboard_note"] for r in results if r.get("tensorboard_note")})
    text = (f"# {experiment.title} ({scale} scale)\n\nReproduces: {experiment.reproduces}\n\n"
            f"{table}\n{note}\n{extra}\n" + "".join(f"\n{n}\n" for n in notes)
            + "\n" + "".join(f"- {k}: {v}\n" for k, v in env.items()))
    atomic_write_text(out / "table.md", text)
    summary = {"experiment": experiment.name, "scale": scale, "environment": env,
               "groups": [{"dataset": d, "model": m, "label": lb, "seeds": [r["seed"] for r in rs],
                           "metrics": [r["metrics"] for r in rs]}
                          for (d, m, lb), rs in groups.items()]}
    atomic_write_text(out / "results.json", json.dumps(summary, indent=1))
    return {"table": table, "files": [str(f) for f in files]}
