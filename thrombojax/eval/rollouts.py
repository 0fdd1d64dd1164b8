"""Rollouts of whole simulations, measured against the truth and the constant-velocity baseline.

:func:`rollout_simulation` rolls a surrogate out from frame ``t0`` (after the dataset's skipped
frames, :func:`thrombojax.study.skip_frames`) to the end, on the full cloud or on a fixed seeded
node subset, with the constant-velocity baseline and the ground truth measured beside it (MSE per
step, clot centroid error, fraction of clot nodes outside the vessel).

Full-resolution clouds roll out on the cell grid: the step's
:class:`~thrombojax.graph.grid.GridSpec` is sized from the simulation's own frames
(:func:`thrombojax.simulator.grid_step.allocate_grid`; only buffer sizes, never the result, depend
on them) and re-allocated when the rollout overflows; small clouds keep the dense search.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from thrombojax.data.augment import subsample_indices
from thrombojax.errors import ConfigError
from thrombojax.eval.metrics import (
    centroid_error,
    fit_vessel_wall,
    fraction_outside,
    horizon_mse,
    mse_per_step,
)
from thrombojax.eval.uncertainty import uncertainty_summary
from thrombojax.models.registry import Surrogate
from thrombojax.simulator.ensemble import ensemble_rollout
from thrombojax.simulator.grid_step import allocate_grid
from thrombojax.simulator.guard_set import build_guards
from thrombojax.simulator.rollout import (
    as_step,
    constant_velocity_rollout,
    guarded_unroll,
    rollout_with_corrections,
)
from thrombojax.simulator.step import LearnedStep
from thrombojax.types import TargetStats, clot_mask

__all__ = ["RolloutResult", "rollout_simulation"]


@dataclasses.dataclass(frozen=True)
class RolloutResult:
    """One rollout measured against the truth and the constant-velocity baseline.

    Attributes:
        name: simulation name. t0: the frame the rollout starts from (s_{t0} given).
        node_index: ``[n]`` indices of the nodes rolled out (a subset or all).
        node_type: ``[n]`` their NodeType values.
        initial: ``[2, n, 3]`` the given frames s_{t0-1}, s_{t0} (scaled).
        pred, true, baseline: ``[n_steps, n, 3]`` frames t0+1 .. t0+n_steps (scaled).
        curves: label -> {"mse", "centroid_error", "fraction_outside"} ``[n_steps]`` arrays,
            labels: the model's name, "constant velocity", and "ground truth" (containment only).
        summary: JSON-ready horizon MSEs and final values per label (with guards: the largest
            correction of each guard, ``max_guard_<name>``; an ensemble's guarded mean also
            ``max_guard_mean_<name>``, how far the guards moved the mean).
        spread: ``[n_steps, n]`` per-node spread of an ensemble rollout (``None`` otherwise).
    """

    name: str
    t0: int
    node_index: np.ndarray
    node_type: np.ndarray
    initial: np.ndarray
    pred: np.ndarray
    true: np.ndarray
    baseline: np.ndarray
    curves: dict
    summary: dict
    spread: np.ndarray | None = None


def rollout_simulation(
    model: Surrogate | LearnedStep,
    params: dict,
    stats: TargetStats,
    positions: np.ndarray,
    node_type: np.ndarray,
    *,
    name: str = "simulation",
    t0: int = 5,
    n_steps: int | None = None,
    n_nodes: int | None = None,
    seed: int = 0,
    wall_cells: np.ndarray | None = None,
    guard_radius: float | None = None,
    ensemble: bool = False,
    centring_r: float | None = None,
    pace: float | None = None,
    coherence_r: float | None = None,
    coherence_stretch: float | None = None,
    keep_wall_velocity: bool = False,
) -> RolloutResult:
    """Roll a model out on one simulation and measure it (scaled coordinates throughout).

    Args:
        model, params, stats: the surrogate (or its learned step), parameters and statistics.
        positions: ``[T, N, 3]`` scaled positions of the full simulation.
        node_type: ``[N]`` NodeType values.
        name: simulation name (labels only).
        t0: start frame, >= 1 (frames before it are skipped; s_{t0-1}, s_{t0} are given).
        n_steps: predicted frames (default: to the end, ``T - 1 - t0``).
        n_nodes: keep a fixed seeded subset of this many nodes (clot fraction kept), or all.
        seed: subset seed.
        wall_cells: ``[F, 3]`` wall triangles of the full simulation, if it has them (better
            wall normals and open-end detection for the containment test).
        guard_radius: one vessel radius in scaled coordinates: apply the physics guards
            (:func:`thrombojax.simulator.guard_set.build_guards`) after every step and record
            their per-step largest correction in the curves (``guard_<name>``); ``None``: the
            model alone.
        ensemble: ``params`` is a member-stacked pytree: the prediction is the ensemble mean
            and ``curves[model]["spread"]`` its mean per-step spread over clot nodes
            (:mod:`thrombojax.simulator.ensemble`); ``result.spread`` holds ``[n, N]``.
        centring_r: with the guards, also the centring guard at this tolerance in vessel radii
            (:mod:`thrombojax.simulator.centring`; ``None``: off); it needs ``guard_radius``.
        pace: with the guards, every clot node's learned step times this factor before they
            act (:meth:`thrombojax.simulator.guard_set.GuardSet.pace_step`; ``None``: off); it
            needs ``guard_radius``.
        coherence_r: with the guards, the coherence guard's tolerance in vessel radii (the
            part of a clot node's deviation from a rigid copy of the start frame beyond it is
            pulled back; ``None``: :func:`~thrombojax.simulator.guard_set.build_guards`'s
            default, 1 r); it needs ``guard_radius``.
        coherence_stretch: with the guards, the coherence guard's copy of the start frame may
            stretch, without a change of volume, up to this principal stretch (>= 1;
            ``build_guards``' ``max_stretch``; ``None``: a rigid copy); it needs ``guard_radius``.
        keep_wall_velocity: with the guards, the step after containment reads the velocity
            from before it (``build_guards``' ``keep_velocity_wall``); it needs ``guard_radius``.
    Returns:
        The :class:`RolloutResult`.
    """
    n_frames = positions.shape[0]
    t0 = int(t0)
    if not 1 <= t0 <= n_frames - 2:
        raise ConfigError(f"simulation '{name}': start frame {t0} must be in 1..{n_frames - 2} "
                          f"({n_frames} frames)")
    max_steps = n_frames - 1 - t0
    n_steps = max_steps if n_steps is None else int(n_steps)
    if centring_r is not None and guard_radius is None:
        raise ConfigError(f"simulation '{name}': centring is a guard: it needs the guards on")
    if pace is not None and guard_radius is None:
        raise ConfigError(f"simulation '{name}': pace acts with the guards: it needs them on")
    if (coherence_r is not None or coherence_stretch is not None) and guard_radius is None:
        raise ConfigError(f"simulation '{name}': the coherence tolerance and stretch are a "
                          "guard's: they need the guards on")
    if keep_wall_velocity and guard_radius is None:
        raise ConfigError(f"simulation '{name}': the velocity kept through containment is a "
                          "guard's: it needs the guards on")
    if not 1 <= n_steps <= max_steps:
        raise ConfigError(f"simulation '{name}': n_steps {n_steps} must be in 1..{max_steps} from "
                          f"frame {t0}")
    idx = subsample_indices(seed, node_type, n_nodes or positions.shape[1])
    sub_type = np.asarray(node_type)[idx]
    x_last, x0 = positions[t0 - 1, idx], positions[t0, idx]
    step = as_step(model)
    x_prev = step.previous(positions, t0)[..., idx, :]  # the step's history
    mask = np.ones(idx.size, bool)
    guards = None if guard_radius is None else build_guards(
        positions[0], node_type, x0, sub_type, radius=guard_radius, wall_cells=wall_cells,
        centring_r=centring_r, pace=pace, max_stretch=coherence_stretch,
        keep_velocity_wall=keep_wall_velocity,
        **({} if coherence_r is None else {"tolerance_r": float(coherence_r)}))
    spread = None
    if ensemble:
        ens = ensemble_rollout(model, params, stats, x_prev, x0, sub_type, mask, n_steps,
                               rollout_fn=None if guards is None else guarded_unroll,
                               context=guards, guard_mean=guards is not None)
        pred, spread = np.asarray(ens.mean), np.asarray(ens.spread)
        corrections = {} if ens.aux is None else {  # the largest over members, and the mean's
            k: np.asarray(v).max(axis=0) for k, v in ens.aux.items()}
        corrections |= {f"mean_{k}": np.asarray(v)
                        for k, v in (ens.mean_corrections or {}).items()}
    else:
        if step.grid is None:  # the grid where it pays, sized from the frames rolled out
            step = allocate_grid(step, positions[t0 - 1:t0 + 1 + n_steps][:, idx], sub_type)
        traj, corrections = rollout_with_corrections(step, params, stats, x_prev, x0, sub_type,
                                                     mask, n_steps, guards=guards)
        pred = np.asarray(traj)
    true = positions[t0 + 1:t0 + 1 + n_steps][:, idx]
    base = constant_velocity_rollout(x_last, x0, sub_type, mask, n_steps)
    clot = clot_mask(sub_type)
    wall = fit_vessel_wall(positions[0], node_type, wall_cells=wall_cells)  # full res, rigid
    curves, summary = {}, {}
    label = getattr(model, "name", "model")
    for key, traj in ((label, pred), ("constant velocity", base), ("ground truth", true)):
        c = {"fraction_outside": fraction_outside(wall, traj, clot)}
        if key != "ground truth":
            c["mse"] = mse_per_step(traj, true, clot)
            c["centroid_error"] = centroid_error(traj, true, clot)
            summary[key] = horizon_mse(c["mse"]) | {
                "final_centroid_error": float(c["centroid_error"][-1]),
            }
        summary.setdefault(key, {})["final_fraction_outside"] = float(c["fraction_outside"][-1])
        summary[key]["max_fraction_outside"] = float(c["fraction_outside"].max())
        curves[key] = c
    for guard, moved in corrections.items():  # the model is wrong where the guards act
        curves[label][f"guard_{guard}"] = np.asarray(moved).max(axis=1)
        summary[label][f"max_guard_{guard}"] = float(np.asarray(moved).max())
    if spread is not None:  # how well the ensemble's spread predicts its error (scaled units)
        curves[label]["spread"] = spread[:, clot].mean(axis=1)
        summary[label]["uncertainty"] = uncertainty_summary(pred, spread, true, sub_type)
    return RolloutResult(name, t0, idx, sub_type, np.stack([x_last, x0]), pred, true, base,
                         curves, summary, spread)
