"""The stability ladder's measurement (``experiments/ladder.py``): one rung's trained runs,
a model or an ensemble (independent members or a committee), rolled out on held-out
simulations and measured against constant velocity in vessel radii."""

from __future__ import annotations

import dataclasses
import json
import pathlib

import numpy as np

from thrombojax import study
from thrombojax.data.augment import subsample_indices
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.drift import (
    centroid_speed,
    direction_carry,
    history_gain,
    speed_carry,
    swell_carry,
)
from thrombojax.eval.metrics import (
    centroid_error,
    fit_vessel_wall,
    fraction_outside,
    mse_per_step,
)
from thrombojax.eval.single_step import (
    ensemble_single_step_errors,
    scaled_simulation,
    single_step_errors,
)
from thrombojax.eval.track import size_ratio, track_errors
from thrombojax.eval.uncertainty import uncertainty_summary
from thrombojax.io.hdf5 import open_dataset
from thrombojax.models.registry import create_model, identity_stats
from thrombojax.simulator.committee import committee_rollout
from thrombojax.simulator.ensemble import ensemble_rollout, stack_params
from thrombojax.simulator.guard_set import build_guards
from thrombojax.simulator.rollout import (
    constant_velocity_rollout,
    guarded_unroll,
    rollout_with_corrections,
)
from thrombojax.simulator.rotations import RotatedStep, fixed_rotations
from thrombojax.simulator.step import make_step
from thrombojax.train.state import load_trained
from thrombojax.types import clot_mask

__all__ = ["evaluate_runs", "members_alone"]


def evaluate_runs(runs: list[pathlib.Path], data: str, guards: bool,
                  n_nodes: int | None = None, names: list[str] | None = None,
                  which: str = "best", committee: bool = False,
                  guard_options: dict | None = None, step_options: dict | None = None,
                  rotations: int | np.ndarray = 0) -> dict:
    """Roll the runs (one model, or an ensemble; each run's ``which`` checkpoint) out on the
    simulations ``names`` of ``data`` (default: the first run's test split) and measure them
    against constant velocity. An ensemble is rolled out as independent members (their mean
    guarded) or, with ``committee``, as a committee (the members' mean step fed back).
    ``guard_options``: keyword arguments of ``build_guards`` (e.g. ``{"coherence": False}``).
    ``step_options``: fields of the learned step replaced at rollout time (e.g.
    ``{"lateral_radius": 0.06}``, the lateral hold on models trained without it).
    ``rotations`` > 0: every model is rolled out on that many copies of each simulation,
    turned by ``fixed_rotations(rotations)`` (the first unturned; or by the ``[R, 3, 3]``
    matrices given) and turned back (``thrombojax.simulator.rotations``), all of them members
    of one ensemble."""
    members = [load_trained(run, which=which) for run in runs]
    trained = members[0]
    ds = open_dataset(data)
    skip = max(study.skip_frames(ds), 1)
    r = vessel_radius(ds) / float(trained.scaling.scale)  # one radius, scaled coordinates
    step = dataclasses.replace(trained.step, **(step_options or {}))
    cv = make_step(create_model("constant_velocity"))
    params = [m.params for m in members]
    turned = np.ndim(rotations) > 0 or bool(rotations)
    if turned:  # each model on each turned copy: a member per (model, rotation)
        rots = np.asarray(rotations) if np.ndim(rotations) else fixed_rotations(int(rotations))
        step = RotatedStep.of(step)
        params = [{"inner": p, "rotation": rot} for p in params for rot in rots]
    per_sim = {}
    for name in trained.split.test if names is None else names:
        full, full_nt = scaled_simulation(ds, name, trained.scaling)
        idx = subsample_indices(0, full_nt, n_nodes or len(full_nt))  # the study's 2,048
        pos, nt = full[:, idx], full_nt[idx]
        m1 = ensemble_single_step_errors(step, params, trained.stats, pos, nt, start_from=skip)
        c1 = single_step_errors(cv, {}, identity_stats(), pos, nt)
        phase = np.arange(1, pos.shape[0] - 1) >= skip
        n = pos.shape[0] - 1 - skip
        mask = np.ones(len(nt), bool)
        g = build_guards(full[0], full_nt, pos[skip], nt, radius=r,
                         wall_cells=ds[name].wall_cells, **(guard_options or {})) \
            if guards else None
        true = pos[skip + 1:]
        extra = {}
        if len(params) == 1:
            pred, corr = rollout_with_corrections(step, params[0], trained.stats,
                                                  step.previous(pos, skip), pos[skip], nt, mask, n,
                                                  guards=g)
        elif committee:
            ens = committee_rollout(step, stack_params(params), trained.stats,
                                    step.previous(pos, skip), pos[skip], nt, mask, n, guards=g)
            pred, corr = ens.mean, ens.mean_corrections or {}
            extra = {"uncertainty": uncertainty_summary(np.asarray(ens.mean),
                                                        np.asarray(ens.spread), true, nt,
                                                        scale=1.0 / r)}
        else:
            ens = ensemble_rollout(step, stack_params(params), trained.stats,
                                   step.previous(pos, skip),
                                   pos[skip], nt, mask, n,
                                   rollout_fn=guarded_unroll if g is not None else None,
                                   context=g, guard_mean=g is not None)
            pred, corr = ens.mean, ens.aux or {}
            extra = {"uncertainty": uncertainty_summary(np.asarray(ens.mean),
                                                        np.asarray(ens.spread), true, nt,
                                                        scale=1.0 / r),
                     "max_mean_correction_r": max(  # how far the guards moved the mean
                         (float(np.asarray(c).max())
                          for c in (ens.mean_corrections or {}).values()), default=0.0) / r}
        pred = np.asarray(pred)
        base = constant_velocity_rollout(pos[skip - 1], pos[skip], nt, mask, n)
        clot = clot_mask(nt)
        wall = fit_vessel_wall(full[0], full_nt, wall_cells=ds[name].wall_cells)
        mse, mse_cv = mse_per_step(pred, true, clot) / r**2, mse_per_step(base, true, clot) / r**2
        outside, centroid = fraction_outside(wall, pred, clot), centroid_error(pred, true, clot) / r
        if len(params) == 1 and not turned and step.history >= 2:  # thrombojax.eval.drift
            extra["history_gain"] = float(history_gain(
                step, trained.params, trained.stats, pos, nt, np.arange(skip, pos.shape[0] - 1),
                delta=0.01 * r).mean())
        if len(params) == 1 and not turned:
            extra["speed_carry"] = float(speed_carry(
                step, trained.params, trained.stats, pos, nt, np.arange(skip, pos.shape[0] - 1),
                delta=0.05).mean())
            extra["direction_carry"] = float(direction_carry(
                step, trained.params, trained.stats, pos, nt, np.arange(skip, pos.shape[0] - 1),
                angle=0.1).mean())
            extra["swell_carry"] = float(swell_carry(
                step, trained.params, trained.stats, pos, nt, np.arange(skip, pos.shape[0] - 1),
                delta=0.02).mean())
        along, across = track_errors(pred, true, clot, start=pos[skip])
        size = size_ratio(pred, true, clot)
        per_sim[name] = {
            "mse1_all": float(m1.mean()) / r**2, "mse1_all_cv": float(c1.mean()) / r**2,
            "mse1_phase": float(m1[phase].mean()) / r**2,
            "mse1_phase_cv": float(c1[phase].mean()) / r**2,
            "mse10": float(mse[:10].mean()), "mse10_cv": float(mse_cv[:10].mean()),
            "mse_full": float(mse.mean()), "mse_full_cv": float(mse_cv.mean()),
            "final_centroid_r": float(centroid[-1]),
            "final_centroid_cv_r": float(centroid_error(base, true, clot)[-1]) / r,
            "max_outside": float(outside.max()),
            "max_outside_cv": float(fraction_outside(wall, base, clot).max()),
            "max_correction_r": max((float(np.asarray(c).max()) for c in corr.values()),
                                    default=0.0) / r,
            "mse_per_step": mse.tolist(), "mse_per_step_cv": mse_cv.tolist(),
            "outside_per_step": outside.tolist(), "centroid_per_step_r": centroid.tolist(),
            "speed_per_step_r": (centroid_speed(np.concatenate([pos[skip:skip + 1], pred]), clot)
                                 / r).tolist(),
            "speed_true_per_step_r": (centroid_speed(pos[skip:], clot) / r).tolist(),
            # the centroid error along / across the true track, the clot's size against the
            # truth's (thrombojax.eval.track)
            "final_along_r": float(along[-1]) / r, "final_across_r": float(across[-1]) / r,
            "final_size_ratio": float(size[-1]),
            "along_per_step_r": (along / r).tolist(), "across_per_step_r": (across / r).tolist(),
            "size_ratio_per_step": size.tolist(),
            **extra,
        }
    keys = [k for k, v in next(iter(per_sim.values())).items()
            if not k.startswith("mse_per_step") and isinstance(v, float)]
    mean = {k: float(np.mean([s[k] for s in per_sim.values()])) for k in keys}
    for k in ("max_outside", "max_outside_cv", "max_correction_r", "max_mean_correction_r"):
        if k in mean:  # the mean's correction: guarded ensembles only
            mean[k] = float(np.max([s[k] for s in per_sim.values()]))
    return {"simulations": per_sim, "mean": mean, "skip_frames": skip, "n_nodes": len(idx),
            "members": len(params), "models": len(members),
            "rotations": len(params) // len(members) if turned else 0,
            "epochs": json.loads((runs[0] / "config.json").read_text())["train"]["epochs"]}


def members_alone(runs: list[pathlib.Path], data: str, guards: bool,
                  n_nodes: int | None, which: str = "best",
                  rotations: int | np.ndarray = 0) -> list[dict]:
    """Each member of an ensemble evaluated alone (with its ``rotations``, as
    :func:`evaluate_runs`): how much one recipe varies with its seed."""
    out = []
    for run in runs:
        res = evaluate_runs([run], data, guards, n_nodes, which=which, rotations=rotations)
        mean = res["mean"]
        seed = json.loads((run / "config.json").read_text())["train"]["seed"]
        # the final error along the true track per simulation, signed (+: ahead of the true
        # clot): whether the members share the ensemble's bias or scatter about it
        along = {name: sim["final_along_r"] for name, sim in res.get("simulations", {}).items()
                 if "final_along_r" in sim}
        out.append({"seed": seed, "mse_full_ratio": mean["mse_full"] / mean["mse_full_cv"],
                    "final_centroid_r": mean["final_centroid_r"],
                    "mse1_phase_ratio": mean["mse1_phase"] / mean["mse1_phase_cv"],
                    "max_outside": mean["max_outside"], "final_along_r": along})
    return out
