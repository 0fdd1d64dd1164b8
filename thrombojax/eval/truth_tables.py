"""The markdown of ``evaluate.md`` and ``rollout.md``: every error beside constant velocity.

Pure functions of the JSON-ready results of :func:`thrombojax.eval.single_step.evaluate_run`
and :func:`thrombojax.eval.report.rollout_run`. Every table states its errors in scaled
[-1, 1] coordinates and in vessel radii (``r``; the conversion, :mod:`thrombojax.eval.physical`,
is written above the tables), always with constant velocity (CV) beside the model and the ratio
model / CV. Missing values (a horizon longer than the rollout, a phase without windows) read
``n/a``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from thrombojax.eval.physical import CV_LABEL, ratio
from thrombojax.eval.tables import markdown_table
from thrombojax.simulator.guard_set import FIXED_COHERENCE_R

__all__ = ["evaluate_markdown", "rollout_markdown"]

GT_LABEL = "ground truth"


def _environment_lines(result: Mapping) -> str:
    """Where the figures were measured (date, command, device, versions, load), from the
    result's ``environment`` (:func:`thrombojax.eval.tables.environment`); empty for older
    results without one."""
    env = result.get("environment")
    if not env:
        return ""
    return "\n## Measured\n\n" + "".join(f"- {k}: {v}\n" for k, v in env.items())


def _cells(row: Sequence[Any]) -> list[Any]:
    return ["n/a" if v is None else v for v in row]


def _units_lines(result: Mapping) -> str:
    u = result["units"]
    unit = u["dataset_units"] or "dataset units"
    return (f"Vessel radius r = {u['vessel_radius']:.4g} {unit} ({u['vessel_radius_source']}); "
            f"one scaled unit = {u['radii_per_scaled_unit']:.4g} r. MSE in r^2 = scaled MSE x "
            f"{u['radii_per_scaled_unit'] ** 2:.4g}; RMSE in r = sqrt(scaled MSE) x "
            f"{u['radii_per_scaled_unit']:.4g} (per-coordinate RMS over clot nodes).\n\n")


def _phase_lines(result: Mapping) -> str:
    defs = "; ".join(f"**{k}**: {v}" for k, v in result["phase_definitions"].items())
    return (f"Phases of a window (s_t-1, s_t, s_t+1), with the dataset's skip_frames = "
            f"{result['skip_frames']}: {defs}.\n\n")


def evaluate_markdown(result: Mapping) -> tuple[str, str]:
    """``evaluate.md`` of an evaluation result, and its main table (by phase, all simulations).

    Returns:
        ``(markdown, table)``.
    """
    model = result["model"]
    header = ["phase", "windows", f"{model} MSE", "constant velocity MSE", f"{model} MSE (r^2)",
              "constant velocity MSE (r^2)", f"{model} RMSE (r)", "constant velocity RMSE (r)",
              f"{model} / constant velocity"]
    rows = [_cells([name, p["windows"], p["mse"], p["constant_velocity_mse"], p["mse_r2"],
                    p["constant_velocity_mse_r2"], p["rmse_r"], p["constant_velocity_rmse_r"],
                    p["ratio_to_cv"]]) for name, p in result["phases"].items()]
    table = markdown_table(header, rows)
    sim_rows = []
    for name, s in result["simulations"].items():
        row = [name, s["windows"], s["exit_frame"]]
        for phase in ("all", "rollout"):
            p = s["phases"][phase]
            row += [p["mse"], p["constant_velocity_mse"], p["rmse_r"],
                    p["constant_velocity_rmse_r"], p["ratio_to_cv"]]
        sim_rows.append(_cells(row))
    sim_header = ["simulation", "windows", "exit frame"] + [
        f"{what} ({phase})" for phase in ("all", "rollout phase")
        for what in ("MSE", "CV MSE", "RMSE (r)", "CV RMSE (r)", "model / CV")]
    sel = result["selection"]
    markdown = (
        f"# Single-step MSE of {model} beside constant velocity\n\n"
        f"Run {result['run_dir']} (checkpoint {result['checkpoint']}) on dataset "
        f"{result['dataset']}: {len(sel['simulations'])} simulation(s), {sel['how']}.\n\n"
        f"Metric: {result['metric']}.\n\n" + _units_lines(result) + _phase_lines(result)
        + "## All simulations, by phase\n\n" + table
        + "\n## Per simulation (exit frame: first frame with a clot node past the vessel's "
          "open end; n/a: the clot stays inside)\n\n"
        + markdown_table(sim_header, sim_rows) + _environment_lines(result))
    return markdown, table


def _mean(values: list[Any]) -> float | None:
    return None if any(v is None for v in values) or not values else float(np.mean(values))


def _predictor_rows(sims: Mapping[str, Mapping], model: str, in_r: bool) -> list[list[Any]]:
    """Rows (simulation, predictor, 1-step all, 1-step rollout phase, horizons..., centroid,
    max % outside, MSE@full / CV) of each simulation, then the mean over simulations."""
    sfx = "_r2" if in_r else ""
    horizons = ("mse@10", "mse@full") if in_r else ("mse@1", "mse@10", "mse@50", "mse@full")
    per: dict[str, list[list[Any]]] = {}
    rows = []
    for name, rep in sims.items():
        ss = rep["single_step"]
        for label in (model, CV_LABEL, GT_LABEL):
            s = rep["summary"].get(label, {})
            outside = 100.0 * s.get("max_fraction_outside", np.nan)
            if label == GT_LABEL:
                values = [None] * (2 + len(horizons) + (2 if in_r else 1)) + [outside, None]
            else:
                key = "" if label == model else "constant_velocity_"
                one = [ss[p][f"{key}mse{sfx}"] for p in ("all", "rollout")]
                hor = [s.get(f"{h}{sfx}") for h in horizons]
                extra = [s.get("rmse@full_r")] if in_r else []
                cent = s.get("final_centroid_error_r" if in_r else "final_centroid_error")
                rat = s.get("ratio_to_cv", {}).get("mse@full") if label == model else 1.0
                values = one + hor + extra + [cent, outside, rat]
            per.setdefault(label, []).append(values)
            rows.append([name, label, *values])
    if len(sims) > 1:
        for label, vals in per.items():
            means = [_mean([v[i] for v in vals]) for i in range(len(vals[0]))]
            if label == model:
                full = horizons.index("mse@full") + 2
                cv_full = _mean([v[full] for v in per[CV_LABEL]])
                means[-1] = ratio(means[full], cv_full)
            rows.append(["**mean**", label, *means])
    return [_cells(r) for r in rows]


def _guard_lines(result: Mapping) -> str:
    """One line saying whether the guards acted and at which tolerances."""
    if not result.get("guards"):
        return "Guards: off (the model alone).\n\n"
    fit, stretch = result.get("coherence_fit"), result.get("coherence_stretch")
    copy = ("a rigid copy" if stretch is None else
            f"a copy stretching up to {stretch:.3g}x at constant volume")
    how = (f"fitted on the run's {len(fit['simulations'])} training simulation(s), the "
           f"{fit['quantile']:.0%} quantile of their clots' distances from {copy} of "
           f"frame {fit['start']}" if fit else "fixed")
    centring, tolerance = result.get("centring_r"), result.get("coherence_r")
    return ("Guards: on: containment; coherence "
            + ("" if stretch is None else f"to {copy} ")
            + f"with a tolerance of {FIXED_COHERENCE_R if tolerance is None else tolerance:.3g} "
            f"r ({how})"
            + (f"; centring within {centring:.3g} r" if centring is not None else "")
            + ("; the step after containment reads the velocity from before it"
               if result.get("keep_wall_velocity") else "") + ".\n\n")


def _pull_line(result: Mapping) -> str:
    """One line naming the prior's centring pull, when the rollout's step had one."""
    pull = result.get("centre_pull") or {}
    if not pull.get("at"):
        return ""
    fit = pull.get("fit")
    how = (f", the median offset of the run's {len(fit['simulations'])} training simulation(s)' "
           "clots" if fit else "")
    tol = pull.get("tolerance_r")
    return (f"Centring pull of the vessel-following prior (set at {pull['at']}): strength "
            f"{pull['strength']:.3g}, tolerance "
            f"{'n/a' if tol is None else format(tol, '.3g')} r{how}.\n\n")


def rollout_markdown(result: Mapping) -> tuple[str, str]:
    """``rollout.md`` of a rollout result, and its main table (vessel radii).

    Args:
        result: ``{"model", "units", "skip", "skip_frames", "phase_definitions", "simulations":
            {name: {"summary": label -> rollout metrics (with the vessel-radius keys of
            :func:`thrombojax.eval.physical.summary_in_radii`), "single_step": phase -> ...}}}``.
    Returns:
        ``(markdown, table)``.
    """
    model, sims = result["model"], result["simulations"]
    head = ["simulation", "predictor", "1-step MSE all", "1-step MSE rollout phase"]
    table_r = markdown_table(
        [*[h + (" (r^2)" if "MSE" in h else "") for h in head], "MSE@10 (r^2)",
         "MSE@full (r^2)", "RMSE@full (r)", "final centroid error (r)", "max % outside",
         "MSE@full / CV"],
        _predictor_rows(sims, model, in_r=True))
    table_s = markdown_table(
        [*head, "MSE@1", "MSE@10", "MSE@50", "MSE@full", "final centroid error (scaled)",
         "max % outside", "MSE@full / CV"],
        _predictor_rows(sims, model, in_r=False))
    starts = sorted({rep["t0"] for rep in sims.values()})
    markdown = (
        f"# Rollouts of {model} beside constant velocity (clot nodes)\n\n"
        f"Dataset {result['dataset']}: {len(sims)} simulation(s), {result['selection']['how']}. "
        f"Rollouts start at frame {', '.join(map(str, starts))} (skip {result['skip']}; the "
        f"dataset's skip_frames: {result['skip_frames']}) and run to the end. MSE@h: mean MSE "
        "over the first h rollout steps (n/a: the rollout is shorter); 1-step MSE: teacher-"
        "forced single steps on the same nodes; max % outside: largest share of clot nodes "
        "through the vessel wall in any frame (the truth's row shows the test's floor).\n\n"
        + _units_lines(result) + _guard_lines(result) + _pull_line(result)
        + _phase_lines(result)
        + "## In vessel radii\n\n" + table_r
        + "\n## In scaled [-1, 1] coordinates (the study's unit)\n\n" + table_s
        + f"\nDataset length unit: {result['units']['dataset_units'] or 'not recorded'} "
          "(pictures and ParaView files are in this unit).\n" + _environment_lines(result))
    return markdown, table_r
