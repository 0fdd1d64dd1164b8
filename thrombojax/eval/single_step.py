"""Single-step evaluation of a trained surrogate: the study's test metric, beside the baseline.

- :func:`single_step_errors`: teacher-forced one-step MSE over the clot nodes of every window
  ``(s_{t-1}, s_t, s_{t+1})`` of a simulation, in scaled [-1, 1] coordinates (the study's metric).
- :func:`single_step_by_phase`: the same for the model and constant velocity (CV), split by the
  phase of the simulation (:mod:`thrombojax.eval.phases`), in scaled units and vessel radii.
- :func:`select_simulations`: which simulations a run is measured on (``--sim``, ``--split``, or
  by default its test split on its own dataset and every simulation of any other dataset).
- :func:`evaluate_run` (the ``thrombojax evaluate`` command) writes JSON and markdown tables,
  every error beside CV, in scaled units and in vessel radii (:mod:`thrombojax.eval.physical`).

Rollouts of whole simulations are :mod:`thrombojax.eval.rollouts`; the ``thrombojax rollout``
command is :mod:`thrombojax.eval.report`.
"""

from __future__ import annotations

import functools
import json
import pathlib
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from thrombojax import study
from thrombojax.data.augment import subsample_indices
from thrombojax.data.scaling import Scaling
from thrombojax.errors import ConfigError
from thrombojax.eval.metrics import fit_vessel_wall, mse_per_step
from thrombojax.eval.phases import PHASE_HELP, exit_frame, phase_summary, window_phases
from thrombojax.eval.physical import RadiusUnits, radius_units
from thrombojax.eval.tables import environment
from thrombojax.eval.truth_tables import evaluate_markdown
from thrombojax.io.hdf5 import Dataset, open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.models.registry import create_model, identity_stats
from thrombojax.simulator.step import LearnedStep, make_step
from thrombojax.train.guards import (
    check_finite,
    check_in_box,
    check_split_names,
    dataset_fingerprint,
)
from thrombojax.train.state import TrainedModel, load_trained
from thrombojax.types import TargetStats, clot_mask
from thrombojax.units import check_units
from thrombojax.xla_options import jit as xla_jit
from thrombojax.xla_options import step_model_name

__all__ = [
    "split_names",
    "select_simulations",
    "scaled_simulation",
    "simulation_exit_frame",
    "batched_next",
    "single_step_errors",
    "ensemble_single_step_errors",
    "single_step_by_phase",
    "evaluate_run",
]


def split_names(trained: TrainedModel, names: list[str], split: str = "test") -> list[str]:
    """Simulations of one split of a run, as recorded in its ``config.json``.

    Args:
        trained: the trained run.
        names: the dataset's simulation names (``split="all"`` returns them all).
        split: ``"train"``, ``"val"``, ``"test"`` or ``"all"``.
    Returns:
        The names of that split.
    """
    if split == "all":
        return list(names)
    if split not in ("train", "val", "test"):
        raise ConfigError(f"unknown split '{split}'; use train, val, test or all")
    return list(getattr(trained.split, split))


def _is_training_dataset(trained: TrainedModel, dataset: Dataset) -> bool:
    """Whether ``dataset`` is the one the run was trained on: same fingerprint (names, shapes,
    node types, first / last frames) when the run recorded one, else it holds the test names."""
    recorded = trained.config.get("dataset_fingerprint")
    if isinstance(recorded, dict) and "sha256" in recorded:
        return recorded["sha256"] == dataset_fingerprint(dataset)["sha256"]
    return all(n in dataset for n in trained.split.test)


def select_simulations(
    trained: TrainedModel,
    dataset: Dataset,
    *,
    simulations: list[str] | None = None,
    split: str | None = None,
    dataset_path: Any = None,
    run_dir: Any = None,
) -> tuple[list[str], str]:
    """The simulations a run is measured on, and a sentence saying why those.

    Args:
        trained: the run. dataset: the open dataset it is applied to.
        simulations: names asked for (``--sim``): exactly those.
        split: ``train`` / ``val`` / ``test`` / ``all`` (``--split``): that split of the run.
        dataset_path, run_dir: for messages.
    Returns:
        ``(names, how)``. With neither ``simulations`` nor ``split``: the run's test split when
        ``dataset`` is the run's own dataset (same fingerprint), else every simulation of
        ``dataset`` ("train on A, evaluate on B").
    Raises:
        DatasetError / ConfigError: names the dataset lacks, or an empty split (named).
    """
    if simulations:
        names = list(dict.fromkeys(simulations))
        check_split_names(names, dataset.names, "--sim", dataset_path, run_dir)
        return names, "asked for with --sim"
    if split is None and not _is_training_dataset(trained, dataset):
        return list(dataset.names), (
            f"all {len(dataset.names)} simulations of the dataset: it is not the run's "
            f"training dataset ({trained.config.get('dataset', '?')}), so the run's test "
            "split does not apply")
    split = split or "test"
    names = split_names(trained, dataset.names, split)
    check_split_names(names, dataset.names, split, dataset_path, run_dir)
    how = "all simulations of the dataset (--split all)" if split == "all" else \
        f"the run's '{split}' split"
    return names, how


def scaled_simulation(
    dataset: Dataset, name: str, scaling: Scaling
) -> tuple[np.ndarray, np.ndarray]:
    """``(positions [T, N, 3] float32 scaled, node_type [N] int32)`` of one simulation."""
    pos = np.asarray(scaling.apply(np.asarray(dataset.positions(name), np.float32)), np.float32)
    return pos, np.asarray(dataset.node_type(name), np.int32)


def simulation_exit_frame(positions: np.ndarray, node_type: np.ndarray,
                          wall_cells: np.ndarray | None = None) -> int | None:
    """:func:`thrombojax.eval.phases.exit_frame` of one full-resolution simulation.

    Args:
        positions: ``[T, N, 3]`` (scaled or physical). node_type: ``[N]``.
        wall_cells: ``[F, 3]`` wall triangles when the dataset has them (open ends from the
            mesh; else from the wall point cloud, :func:`thrombojax.eval.metrics.fit_vessel_wall`).
    Returns:
        The first frame with a clot node past an open end (not past at frame 0), or ``None``.
    """
    wall = fit_vessel_wall(positions[0], node_type, wall_cells=wall_cells)
    return exit_frame(wall, positions, clot_mask(node_type))


@functools.partial(xla_jit, model_of=step_model_name, static_argnums=0)
def batched_next(step, params, stats, prev, cur, node_type, mask):
    """Teacher-forced next positions of a batch of windows of one simulation, ``[B, N, 3]``.

    One compilation per step and shapes (the step is static, the parameters an argument), so
    repeated calls with new parameters or frames reuse it. ``prev``: ``[B, ...]`` each
    window's ``x_prev`` (:meth:`~thrombojax.simulator.step.LearnedStep.previous`); ``cur``:
    ``[B, N, 3]``; ``node_type``, ``mask``: ``[N]``. The grid overflow flag is not checked:
    callers require a dense step (:meth:`~thrombojax.simulator.step.LearnedStep.require_dense`).
    """
    def one(p, c):
        return step(params, stats, p, c, node_type, mask).positions

    return jax.vmap(one)(prev, cur)


def single_step_errors(
    step: LearnedStep,
    params: dict,
    stats: TargetStats,
    positions: np.ndarray,
    node_type: np.ndarray,
    *,
    skip: int = 0,
    batch_size: int = 8,
    start_from: int | None = None,
) -> np.ndarray:
    """Teacher-forced one-step MSE over clot nodes for every window of one simulation.

    Args:
        step, params, stats: the learned step (:func:`thrombojax.simulator.step.make_step`), its
            parameters and target statistics.
        positions: ``[T, N, 3]`` scaled positions. node_type: ``[N]`` NodeType values.
        skip: middle frames ``t < skip`` are not evaluated.
        batch_size: windows per compiled call (the last chunk is padded, not truncated).
        start_from: for a step that reads the clot's start speed
            (:mod:`thrombojax.simulator.start_speed`), window ``t`` reads the start speed of frame
            ``min(t, start_from)``, the frame the dataset's rollouts start from, as in training
            (None: of ``t``).
    Returns:
        ``[n_windows]`` MSE per window ``t = max(skip, 1) .. T - 2``.
    """
    return ensemble_single_step_errors(step, [params], stats, positions, node_type, skip=skip,
                                       batch_size=batch_size, start_from=start_from)


def ensemble_single_step_errors(
    step: LearnedStep,
    params_list: list[dict],
    stats: TargetStats,
    positions: np.ndarray,
    node_type: np.ndarray,
    *,
    skip: int = 0,
    batch_size: int = 8,
    start_from: int | None = None,
) -> np.ndarray:
    """:func:`single_step_errors` of the member mean of M models (a deep ensemble's one-step
    prediction: every member predicts s_{t+1} from the true s_{t-1}, s_t; the M predictions
    are averaged). One member gives :func:`single_step_errors` exactly. A step with a history
    of H frames reads the true s_{t-H} .. s_{t-1} (frame 0 repeated before the record starts,
    :meth:`~thrombojax.simulator.step.LearnedStep.previous`), so every model is scored on the
    same windows.

    Args:
        params_list: M >= 1 parameter trees sharing ``step`` and ``stats``.
        step, stats, positions, node_type, skip, batch_size, start_from: as in
            :func:`single_step_errors`.
    Returns:
        ``[n_windows]`` MSE of the mean prediction per window.
    """
    step.require_dense("single-step evaluation")
    if not params_list:
        raise ConfigError("single-step evaluation of an ensemble needs at least one member")
    times = np.arange(max(skip, 1), positions.shape[0] - 1)
    if times.size == 0:
        raise ConfigError(f"no window with skip={skip} in a simulation of {positions.shape[0]} "
                          "frames")
    mask = jnp.ones(positions.shape[1], bool)
    clot = clot_mask(node_type)
    errors = []
    for lo in range(0, times.size, batch_size):
        t = times[lo:lo + batch_size]
        t_pad = np.concatenate([t, np.full(batch_size - t.size, t[-1])])
        x_prev = step.previous(positions, t_pad, start_from=start_from)
        preds = [np.asarray(batched_next(step, params, stats, x_prev,
                                         positions[t_pad], jnp.asarray(node_type), mask))
                 for params in params_list]
        nxt = preds[0] if len(preds) == 1 else np.mean(preds, axis=0)
        errors.append(mse_per_step(nxt[:t.size], positions[t + 1], clot))
    return np.concatenate(errors)


@functools.cache
def _cv_step() -> LearnedStep:
    return make_step(create_model("constant_velocity"))


def single_step_by_phase(
    step: LearnedStep,
    params: dict,
    stats: TargetStats,
    positions: np.ndarray,
    node_type: np.ndarray,
    *,
    skip_frames: int,
    exit_at: int | None,
    units: RadiusUnits,
    skip: int = 0,
    batch_size: int = 8,
) -> tuple[dict[str, np.ndarray], dict[str, dict]]:
    """Teacher-forced single-step MSE of a model and of CV on one simulation, by phase.

    Args:
        step, params, stats: the learned step and its parameters and statistics.
        positions: ``[T, N, 3]`` scaled positions (all nodes or a subset).
        node_type: ``[N]`` NodeType values.
        skip_frames: the dataset's ``skip_frames`` (the start / rollout boundary).
        exit_at: :func:`exit_frame` of the full-resolution simulation, or ``None``.
        units: the conversion to vessel radii.
        skip: windows with middle frame ``t < skip`` are not evaluated at all.
        batch_size: windows per compiled call.
    Returns:
        ``(windows, summary)``: ``windows`` holds ``[W]`` arrays ``"t"`` (middle frames),
        ``"model"``, ``"constant_velocity"`` (MSE, scaled) and one bool mask per phase;
        ``summary`` is :func:`phase_summary`.
    """
    m = single_step_errors(step, params, stats, positions, node_type, skip=skip,
                           batch_size=batch_size, start_from=skip_frames)
    b = single_step_errors(_cv_step(), {}, identity_stats(), positions, node_type, skip=skip,
                           batch_size=batch_size)
    times = np.arange(max(skip, 1), positions.shape[0] - 1)
    phases = window_phases(times, skip_frames=skip_frames, exit_at=exit_at)
    windows = {"t": times, "model": m, "constant_velocity": b, **phases}
    return windows, phase_summary(m, b, phases, units)


def evaluate_run(
    run_dir: str | pathlib.Path,
    dataset_path: str | pathlib.Path,
    *,
    out_dir: str | pathlib.Path | None = None,
    simulations: list[str] | None = None,
    split: str | None = None,
    which: str = "best",
    skip: int = 0,
    batch_size: int = 8,
    n_nodes: int | None = None,
    seed: int = 0,
    progress: bool = True,
    force: bool = False,
) -> dict:
    """Single-step MSE of a trained run on any dataset, by phase, beside constant velocity.

    Args:
        run_dir: the training run directory. dataset_path: any dataset in the run's length unit
            (the run's own, or another: "train on A, evaluate on B").
        out_dir: where ``evaluate.json`` and ``evaluate.md`` go (default: ``run_dir``).
        simulations: evaluate exactly these (``--sim``).
        split: ``"test"``, ``"val"``, ``"train"`` or ``"all"``; default (``None``): the run's
            test split on its own dataset, every simulation of another one
            (:func:`select_simulations`).
        which: checkpoint, ``"best"`` or ``"last"``.
        skip: windows whose middle frame is ``< skip`` are not evaluated (default 0: every
            window). The phases (:mod:`thrombojax.eval.phases`) split at the dataset's own
            ``skip_frames`` attribute (:func:`thrombojax.study.skip_frames`), not at ``skip``.
        batch_size: windows per compiled call.
        n_nodes: evaluate on a fixed seeded node subset of this size per simulation (default:
            the run's ``nodes_per_sample``, else every node). seed: subset seed.
        progress: show a progress bar.
        force: replace an existing ``evaluate.json`` / ``evaluate.md``.
    Returns:
        The JSON-ready result: overall and per-simulation MSE of the model and of constant
        velocity per phase, in scaled units and vessel radii, with the ratio model / CV, the
        conversion (``units``) and the selection (``selection``); ``table``: the markdown.
    """
    out_dir = pathlib.Path(out_dir or run_dir)
    check_targets([out_dir / "evaluate.json", out_dir / "evaluate.md"], inputs=(dataset_path,),
                  force=force, what="evaluation")
    trained = load_trained(run_dir, which=which)
    ds = open_dataset(dataset_path)
    check_units(trained.config, ds, run_dir=run_dir, dataset_path=dataset_path)
    names, how = select_simulations(trained, ds, simulations=simulations, split=split,
                                   dataset_path=dataset_path, run_dir=run_dir)
    units = radius_units(trained.scaling, ds)
    skip_frames = study.skip_frames(ds)
    step = trained.step
    n_nodes = n_nodes or trained.run.train.nodes_per_sample
    per_sim, windows = {}, []
    for name in tqdm(names, desc="evaluate", unit="sim", disable=not progress):
        sim = ds[name]  # validate values as `thrombojax info` does
        pos, node_type = scaled_simulation(ds, name, trained.scaling)
        check_in_box(pos, name, dataset_path, run_dir)
        exit_at = simulation_exit_frame(pos, node_type, sim.wall_cells)
        if n_nodes:
            idx = subsample_indices(seed, node_type, int(n_nodes))
            pos, node_type = pos[:, idx], node_type[idx]
        w, phases = single_step_by_phase(step, trained.params, trained.stats, pos, node_type,
                                         skip_frames=skip_frames, exit_at=exit_at, units=units,
                                         skip=skip, batch_size=batch_size)
        per_sim[name] = {**phases["all"], "exit_frame": exit_at, "phases": phases}
        windows.append(w)
    cat = {k: np.concatenate([w[k] for w in windows]) for k in windows[0]}
    overall = phase_summary(cat["model"], cat["constant_velocity"],
                            {k: cat[k] for k in PHASE_HELP}, units)  # window-weighted
    env = environment()  # device, versions, command and load, beside the figures
    result = {
        "model": trained.model.name, "run_dir": str(run_dir), "dataset": str(dataset_path),
        "selection": {"how": how, "simulations": names}, "split": split,
        "checkpoint": which, "skip": skip, "skip_frames": skip_frames, "n_nodes": n_nodes,
        "metric": "MSE over clot nodes and x, y, z of one teacher-forced step; scaled [-1, 1] "
                  "coordinates (mse) and vessel radii squared (mse_r2); rmse_r = sqrt(mse_r2)",
        "units": units.to_dict(), "phase_definitions": PHASE_HELP,
        **overall["all"], "phases": overall, "simulations": per_sim,
        "date": env["date"], "environment": env,
    }
    check_finite({"mse": result["mse"]}, f"{run_dir}: checkpoint '{which}'")
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out_dir / "evaluate.json", json.dumps(result, indent=2))
    markdown, table = evaluate_markdown(result)
    atomic_write_text(out_dir / "evaluate.md", markdown)
    result["table"] = table
    return result
