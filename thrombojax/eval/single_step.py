"""Single-step evaluation of a trained surrogate: the study's test metric, beside the baseline.

- :func:`single_step_errors`: teacher-forced one-step MSE over the clot nodes of every window
  ``(s_{t-1}, s_t, s_{t+1})`` of a simulation, in scaled [-1, 1] coordinates (the study's metric).
- :func:`evaluate_run` (the ``thrombojax evaluate`` command) writes JSON and a markdown table,
  with the constant-velocity baseline measured the same way.

Rollouts of whole simulations are :mod:`thrombojax.eval.rollouts`; the ``thrombojax rollout``
command is :mod:`thrombojax.eval.report`.
"""

from __future__ import annotations

import datetime
import functools
import json
import pathlib

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from thrombojax.data.augment import subsample_indices
from thrombojax.data.scaling import Scaling
from thrombojax.errors import ConfigError
from thrombojax.eval.metrics import mse_per_step
from thrombojax.eval.tables import markdown_table
from thrombojax.io.hdf5 import Dataset, open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.models.registry import create_model, identity_stats
from thrombojax.simulator.step import LearnedStep, make_step
from thrombojax.train.guards import check_finite, check_in_box, check_split_names
from thrombojax.train.state import TrainedModel, load_trained
from thrombojax.types import TargetStats, clot_mask
from thrombojax.units import check_units

__all__ = [
    "split_names",
    "scaled_simulation",
    "single_step_errors",
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


def scaled_simulation(
    dataset: Dataset, name: str, scaling: Scaling
) -> tuple[np.ndarray, np.ndarray]:
    """``(positions [T, N, 3] float32 scaled, node_type [N] int32)`` of one simulation."""
    pos = np.asarray(scaling.apply(np.asarray(dataset.positions(name), np.float32)), np.float32)
    return pos, np.asarray(dataset.node_type(name), np.int32)


@functools.partial(jax.jit, static_argnums=0)
def _batched_next(step, params, stats, prev, cur, node_type, mask):
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
) -> np.ndarray:
    """Teacher-forced one-step MSE over clot nodes for every window of one simulation.

    Args:
        step, params, stats: the learned step (:func:`thrombojax.simulator.step.make_step`), its
            parameters and target statistics.
        positions: ``[T, N, 3]`` scaled positions. node_type: ``[N]`` NodeType values.
        skip: middle frames ``t < skip`` are not evaluated.
        batch_size: windows per compiled call (the last chunk is padded, not truncated).
    Returns:
        ``[n_windows]`` MSE per window ``t = max(skip, 1) .. T - 2``.
    """
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
        nxt = np.asarray(_batched_next(step, params, stats, positions[t_pad - 1],
                                       positions[t_pad], jnp.asarray(node_type), mask))
        errors.append(mse_per_step(nxt[:t.size], positions[t + 1], clot))
    return np.concatenate(errors)


def evaluate_run(
    run_dir: str | pathlib.Path,
    dataset_path: str | pathlib.Path,
    *,
    out_dir: str | pathlib.Path | None = None,
    split: str = "test",
    which: str = "best",
    skip: int = 0,
    batch_size: int = 8,
    n_nodes: int | None = None,
    seed: int = 0,
    progress: bool = True,
    force: bool = False,
) -> dict:
    """Single-step MSE of a trained run on one split, beside the constant-velocity baseline.

    Args:
        run_dir: the training run directory. dataset_path: the dataset it was trained on.
        out_dir: where ``evaluate.json`` and ``evaluate.md`` go (default: ``run_dir``).
        split: ``"test"`` (default), ``"val"``, ``"train"`` or ``"all"``.
        which: checkpoint, ``"best"`` or ``"last"``.
        skip: middle frames ``t < skip`` are not evaluated (default 0: every window).
        batch_size: windows per compiled call.
        n_nodes: evaluate on a fixed seeded node subset of this size per simulation (default:
            the run's ``nodes_per_sample``, else every node). seed: subset seed.
        progress: show a progress bar.
        force: replace an existing ``evaluate.json`` / ``evaluate.md``.
    Returns:
        The JSON-ready result: per simulation and overall MSE of model and baseline.
    """
    out_dir = pathlib.Path(out_dir or run_dir)
    check_targets([out_dir / "evaluate.json", out_dir / "evaluate.md"], inputs=(dataset_path,),
                  force=force, what="evaluation")
    trained = load_trained(run_dir, which=which)
    ds = open_dataset(dataset_path)
    check_units(trained.config, ds, run_dir=run_dir, dataset_path=dataset_path)
    names = split_names(trained, ds.names, split)
    check_split_names(names, ds.names, split, dataset_path, run_dir)
    step = make_step(trained.model)
    cv = make_step(create_model("constant_velocity"))
    n_nodes = n_nodes or trained.run.train.nodes_per_sample
    per_sim, all_model, all_base = {}, [], []
    for name in tqdm(names, desc=f"evaluate {split}", unit="sim", disable=not progress):
        ds[name]  # validate values as `thrombojax info` does
        pos, node_type = scaled_simulation(ds, name, trained.scaling)
        check_in_box(pos, name, dataset_path, run_dir)
        if n_nodes:
            idx = subsample_indices(seed, node_type, int(n_nodes))
            pos, node_type = pos[:, idx], node_type[idx]
        m = single_step_errors(step, trained.params, trained.stats, pos, node_type,
                               skip=skip, batch_size=batch_size)
        b = single_step_errors(cv, {}, identity_stats(), pos, node_type, skip=skip,
                               batch_size=batch_size)
        per_sim[name] = {"windows": int(m.size), "mse": float(m.mean()),
                         "constant_velocity_mse": float(b.mean())}
        all_model.append(m)
        all_base.append(b)
    result = {
        "model": trained.model.name, "run_dir": str(run_dir), "dataset": str(dataset_path),
        "split": split, "checkpoint": which, "skip": skip, "n_nodes": n_nodes,
        "metric": "MSE over clot nodes and x, y, z, scaled [-1, 1] coordinates, one step",
        "mse": float(np.concatenate(all_model).mean()),
        "constant_velocity_mse": float(np.concatenate(all_base).mean()),
        "simulations": per_sim,
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
    }
    check_finite({"mse": result["mse"]}, f"{run_dir}: checkpoint '{which}'")
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out_dir / "evaluate.json", json.dumps(result, indent=2))
    rows = [[n, r["windows"], r["mse"], r["constant_velocity_mse"]] for n, r in per_sim.items()]
    rows.append(["**all**", sum(r["windows"] for r in per_sim.values()), result["mse"],
                 result["constant_velocity_mse"]])
    table = markdown_table(["simulation", "windows", f"{result['model']} MSE",
                            "constant velocity MSE"], rows)
    atomic_write_text(out_dir / "evaluate.md",
        f"# Single-step {split} MSE ({result['metric']})\n\n{table}")
    result["table"] = table
    return result
