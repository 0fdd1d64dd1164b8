"""Evaluation of a trained surrogate: single-step test MSE and rollouts of whole simulations.

- :func:`single_step_errors`: teacher-forced one-step MSE over the clot nodes of every window
  ``(s_{t-1}, s_t, s_{t+1})`` of a simulation, in scaled [-1, 1] coordinates (the study's metric).
- :func:`rollout_simulation`: one rollout from frame ``t0`` (after the study's skipped frames:
  5 for BendVessel, 40 for ClotEntry) to the end, on the full cloud or on a fixed seeded node
  subset, with the constant-velocity baseline and the ground truth measured beside it
  (MSE per step, clot centroid error, fraction of clot nodes outside the vessel).
- :func:`evaluate_run` (the ``thrombojax evaluate`` command) writes JSON and a markdown table.

The whole-run ``thrombojax rollout`` command lives in :mod:`thrombojax.rollout_report`.
"""

from __future__ import annotations

import dataclasses
import datetime
import functools
import json
import pathlib
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from thrombojax.errors import ConfigError
from thrombojax.metrics import (
    centroid_error,
    clot_mask_of,
    fit_vessel_wall,
    fraction_outside,
    horizon_mse,
    mse_per_step,
)
from thrombojax.rollout import constant_velocity_rollout, predict_next, rollout, select_subset

__all__ = [
    "STUDY_SKIP",
    "default_skip",
    "config_value",
    "split_names",
    "scaled_simulation",
    "single_step_errors",
    "RolloutResult",
    "rollout_simulation",
    "evaluate_run",
    "markdown_table",
]

STUDY_SKIP: dict[str, int] = {"bendvessel": 5, "clotentry": 40}
"""Frames the study skipped before rollouts (the clot is still entering the vessel)."""


def default_skip(dataset: Any) -> int:
    """Skipped frames for a dataset: 40 when its name or generator says ClotEntry, else 5."""
    cfg = dataset.attrs.get("generator_config")
    text = f"{dataset.attrs.get('name', '')} {cfg if cfg else ''}".lower()
    return STUDY_SKIP["clotentry"] if "clotentry" in text else STUDY_SKIP["bendvessel"]


def config_value(config: dict, *keys: str, default: Any = None) -> Any:
    """The first of ``keys`` found in a run config, searching nested dicts depth-first."""
    for key in keys:
        if key in config and config[key] is not None:
            return config[key]
    for value in config.values():
        if isinstance(value, dict):
            found = config_value(value, *keys, default=None)
            if found is not None:
                return found
    return default


def split_names(config: dict, names: list[str], split: str = "test") -> list[str]:
    """Simulations of one split of a run: the run's recorded split, else re-drawn from its seed.

    Args:
        config: the run config (``TrainedModel.config``).
        names: the dataset's simulation names.
        split: ``"train"``, ``"val"``, ``"test"`` or ``"all"``.
    Returns:
        The names of that split.
    """
    if split == "all":
        return list(names)
    if split not in ("train", "val", "test"):
        raise ConfigError(f"unknown split '{split}'; use train, val, test or all")
    recorded = config_value(config, "split", default=None)
    if isinstance(recorded, dict) and split in recorded:
        return list(recorded[split])
    from thrombojax.data.splits import split_simulations

    chosen = split_simulations(
        list(names), n_test=int(config_value(config, "n_test", default=1)),
        n_val=int(config_value(config, "n_val", default=2)),
        seed=int(config_value(config, "split_seed", "seed", default=0)),
    )
    return list(getattr(chosen, split))


def scaled_simulation(dataset: Any, name: str, scaling: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(positions [T, N, 3] float32 scaled, node_type [N] int32)`` of one simulation."""
    pos = np.asarray(scaling.apply(np.asarray(dataset.positions(name), np.float32)), np.float32)
    return pos, np.asarray(dataset.node_type(name), np.int32)


@functools.partial(jax.jit, static_argnums=0)
def _batched_next(model, params, stats, prev, cur, node_type, mask):
    def one(p, c):
        return predict_next(model, params, stats, p, c, node_type, mask)[0]

    return jax.vmap(one)(prev, cur)


def single_step_errors(
    model: Any,
    params: Any,
    stats: Any,
    positions: np.ndarray,
    node_type: np.ndarray,
    *,
    skip: int = 0,
    batch_size: int = 8,
) -> np.ndarray:
    """Teacher-forced one-step MSE over clot nodes for every window of one simulation.

    Args:
        model, params, stats: the surrogate, its parameters and target statistics.
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
    clot = clot_mask_of(node_type)
    errors = []
    for lo in range(0, times.size, batch_size):
        t = times[lo:lo + batch_size]
        t_pad = np.concatenate([t, np.full(batch_size - t.size, t[-1])])
        nxt = np.asarray(_batched_next(model, params, stats, positions[t_pad - 1],
                                       positions[t_pad], jnp.asarray(node_type), mask))
        errors.append(mse_per_step(nxt[:t.size], positions[t + 1], clot))
    return np.concatenate(errors)


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
        summary: JSON-ready horizon MSEs and final values per label.
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


def rollout_simulation(
    model: Any,
    params: Any,
    stats: Any,
    positions: np.ndarray,
    node_type: np.ndarray,
    *,
    name: str = "simulation",
    t0: int = 5,
    n_steps: int | None = None,
    n_nodes: int | None = None,
    seed: int = 0,
    wall_cells: np.ndarray | None = None,
) -> RolloutResult:
    """Roll a model out on one simulation and measure it (scaled coordinates throughout).

    Args:
        model, params, stats: the surrogate, its parameters and target statistics.
        positions: ``[T, N, 3]`` scaled positions of the full simulation.
        node_type: ``[N]`` NodeType values.
        name: simulation name (labels only).
        t0: start frame, >= 1 (frames before it are skipped; s_{t0-1}, s_{t0} are given).
        n_steps: predicted frames (default: to the end, ``T - 1 - t0``).
        n_nodes: keep a fixed seeded subset of this many nodes (clot fraction kept), or all.
        seed: subset seed.
        wall_cells: ``[F, 3]`` wall triangles of the full simulation, if it has them (better
            wall normals and open-end detection for the containment test).
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
    if not 1 <= n_steps <= max_steps:
        raise ConfigError(f"simulation '{name}': n_steps {n_steps} must be in 1..{max_steps} from "
                          f"frame {t0}")
    idx = select_subset(node_type, n_nodes or positions.shape[1], seed=seed)
    sub_type = np.asarray(node_type)[idx]
    x_prev, x0 = positions[t0 - 1, idx], positions[t0, idx]
    mask = np.ones(idx.size, bool)
    pred = np.asarray(rollout(model, params, stats, x_prev, x0, sub_type, mask, n_steps))
    true = positions[t0 + 1:t0 + 1 + n_steps][:, idx]
    base = constant_velocity_rollout(x_prev, x0, sub_type, mask, n_steps)
    clot = clot_mask_of(sub_type)
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
    return RolloutResult(name, t0, idx, sub_type, np.stack([x_prev, x0]), pred, true, base,
                         curves, summary)


def markdown_table(header: list[str], rows: list[list[Any]]) -> str:
    """A GitHub markdown table; floats printed with 4 significant digits (``%.4g``)."""
    def fmt(v):
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(v) for v in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


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
    Returns:
        The JSON-ready result: per simulation and overall MSE of model and baseline.
    """
    from thrombojax.io.hdf5 import open_dataset
    from thrombojax.models.registry import create_model, identity_stats
    from thrombojax.train.state import load_trained
    from thrombojax.units import check_units

    trained = load_trained(run_dir, which=which)
    ds = open_dataset(dataset_path)
    check_units(trained.config, ds, run_dir=run_dir, dataset_path=dataset_path)
    names = split_names(trained.config, ds.names, split)
    cv = create_model("constant_velocity")
    n_nodes = n_nodes or config_value(trained.config, "nodes_per_sample", default=None)
    per_sim, all_model, all_base = {}, [], []
    for name in tqdm(names, desc=f"evaluate {split}", unit="sim", disable=not progress):
        pos, node_type = scaled_simulation(ds, name, trained.scaling)
        if n_nodes:
            idx = select_subset(node_type, int(n_nodes), seed=seed)
            pos, node_type = pos[:, idx], node_type[idx]
        m = single_step_errors(trained.model, trained.params, trained.stats, pos, node_type,
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
    out_dir = pathlib.Path(out_dir or run_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "evaluate.json").write_text(json.dumps(result, indent=2))
    rows = [[n, r["windows"], r["mse"], r["constant_velocity_mse"]] for n, r in per_sim.items()]
    rows.append(["**all**", sum(r["windows"] for r in per_sim.values()), result["mse"],
                 result["constant_velocity_mse"]])
    table = markdown_table(["simulation", "windows", f"{result['model']} MSE",
                            "constant velocity MSE"], rows)
    (out_dir / "evaluate.md").write_text(
        f"# Single-step {split} MSE ({result['metric']})\n\n{table}")
    result["table"] = table
    return result
