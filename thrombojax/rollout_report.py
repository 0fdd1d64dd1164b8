"""The ``thrombojax rollout`` command: roll a trained run out and write everything a user opens.

For each chosen simulation, into ``out_dir``:

- ``<sim>_rollout.h5``: the predicted trajectory in the dataset schema (physical units; frames
  s_{t0-1}, s_{t0}, then the predictions), so every dataset tool (``thrombojax info``,
  ``thrombojax export``) reads it;
- ``<sim>_prediction.xdmf`` / ``<sim>_truth.xdmf`` (+ ``.h5``): ParaView time series with
  ``node_type`` and the per-node ``error`` (distance to the truth) as point data, at the
  physical times ``frame * dt`` (so they play in step with an exported dataset simulation);
- ``<sim>_rollout.gif``: prediction beside ground truth, equal axes, clot coloured by error;
- ``<sim>_summary.png``: the model, constant velocity and the truth side by side at 4 frames;
- ``<sim>_error.png`` (MSE per step) and ``<sim>_metrics.png`` (MSE, centroid error, fraction
  outside the vessel), always with the constant-velocity baseline;
- ``rollout.json`` (all metrics and curves) and ``rollout.md`` (horizon table).
"""

from __future__ import annotations

import datetime
import json
import pathlib
from typing import Any

import numpy as np

from thrombojax.evaluate import (
    RolloutResult,
    config_value,
    default_skip,
    markdown_table,
    rollout_simulation,
    scaled_simulation,
    split_names,
)
from thrombojax.io.export import export_trajectory
from thrombojax.units import check_units
from thrombojax.viz import animate_rollout, plot_error_curves, plot_rollout_metrics
from thrombojax.viz_summary import default_summary_frames, plot_rollout_summary

__all__ = ["subset_cells", "save_rollout", "rollout_run"]


def subset_cells(cells: np.ndarray | None, node_index: np.ndarray, n_nodes: int):
    """Cells whose every node is kept, re-indexed into the subset (``None`` if none remain)."""
    if cells is None:
        return None
    new = np.full(n_nodes, -1, np.int64)
    new[node_index] = np.arange(node_index.size)
    mapped = new[np.asarray(cells)]
    kept = mapped[(mapped >= 0).all(axis=1)].astype(np.int32)
    return kept if kept.size else None


def save_rollout(
    result: RolloutResult,
    sim: Any,
    scaling: Any,
    out_dir: pathlib.Path,
    *,
    model_name: str,
    format: str = "xdmf",
    gif: bool = True,
    units: str = "",
) -> dict[str, str]:
    """Write the files of one rollout (see the module docstring); returns label -> path.

    ``units``: the dataset's length unit (axis labels and colour bars of the pictures).
    """
    from thrombojax.io.hdf5 import Simulation, write_dataset

    n_all = sim.positions.shape[1]
    idx = result.node_index

    def phys(x):
        return np.asarray(scaling.invert(np.asarray(x, np.float32)), np.float32)

    pred = phys(np.concatenate([result.initial, result.pred]))
    true = phys(np.concatenate([result.initial, result.true]))
    clot_cells = subset_cells(sim.clot_cells, idx, n_all)
    wall_cells = subset_cells(sim.wall_cells, idx, n_all)
    dt = float(sim.attrs.get("dt", 1.0))
    stem = out_dir / result.name
    attrs = {"dt": dt, "source_simulation": sim.name, "model": model_name, "t0": result.t0,
             "first_frame": result.t0 - 1,
             "n_nodes_full": n_all, "subset": bool(idx.size < n_all)}
    for key in ("rotation_deg", "seed", "reference_wall_time_s", "solver_wall_time_s"):
        if key in sim.attrs:
            attrs[key] = sim.attrs[key]
    rollout_sim = Simulation(name=f"{result.name}_rollout", positions=pred,
                             node_type=result.node_type.astype(np.int8), clot_cells=clot_cells,
                             wall_cells=wall_cells, attrs=attrs)
    files = {"trajectory": write_dataset(stem.with_name(f"{result.name}_rollout.h5"),
                                         [rollout_sim], name=f"{result.name} rollout",
                                         source=f"thrombojax rollout ({model_name})")}
    error = np.linalg.norm(pred - true, axis=-1)
    common = dict(clot_cells=clot_cells, wall_cells=wall_cells, dt=dt, format=format,
                  first_frame=result.t0 - 1)
    files["prediction"] = export_trajectory(stem.with_name(f"{result.name}_prediction"), pred,
                                            result.node_type, point_data={"error": error},
                                            **common)
    files["truth"] = export_trajectory(stem.with_name(f"{result.name}_truth"), true,
                                       result.node_type, **common)
    files["error_png"] = plot_error_curves(
        {label: c["mse"] for label, c in result.curves.items() if "mse" in c},
        stem.with_name(f"{result.name}_error.png"),
        title=f"{model_name} rollout on {result.name} from frame {result.t0}")
    files["metrics_png"] = plot_rollout_metrics(
        result.curves, stem.with_name(f"{result.name}_metrics.png"),
        title=f"{model_name} rollout on {result.name} (from frame {result.t0}, "
              f"{idx.size} nodes)")
    if gif:
        files["gif"] = animate_rollout(pred, true, result.node_type,
                                       stem.with_name(f"{result.name}_rollout.gif"),
                                       title=f"{model_name} / {result.name}",
                                       first_frame=result.t0 - 1, dt=dt, units=units)
    const = phys(np.concatenate([result.initial, result.baseline]))
    files["summary_png"] = plot_rollout_summary(
        true, pred, const, result.node_type, stem.with_name(f"{result.name}_summary.png"),
        dt=dt, units=units, first_frame=result.t0 - 1,
        frames=1 + default_summary_frames(len(pred) - 1),  # from the given frame s_t0 on
        labels=(model_name, "constant velocity", "ground truth"),
        title=f"{model_name} rollout on {result.name}")
    return {k: str(v) for k, v in files.items()}


def rollout_run(
    run_dir: str | pathlib.Path,
    dataset_path: str | pathlib.Path,
    out_dir: str | pathlib.Path,
    *,
    simulations: list[str] | None = None,
    split: str = "test",
    which: str = "best",
    skip: int | None = None,
    n_steps: int | None = None,
    n_nodes: int | None = None,
    seed: int = 0,
    format: str = "xdmf",
    gif: bool = True,
) -> dict:
    """Roll a trained run out on simulations of a dataset and write trajectories, plots, metrics.

    Args:
        run_dir: training run directory. dataset_path: dataset file. out_dir: output folder.
        simulations: names to roll out (default: the run's ``split``).
        split: split used when ``simulations`` is not given.
        which: checkpoint, ``"best"`` or ``"last"``.
        skip: skipped frames; the rollout starts at frame ``max(skip, 1)`` (default: 5, or 40
            for ClotEntry datasets, as in the study).
        n_steps: predicted frames (default: to the end).
        n_nodes: fixed seeded node subset size (default: the run's ``nodes_per_sample``, the
            density it was trained on, else all nodes).
        seed: subset seed. format: ``"xdmf"`` or ``"vtu"``. gif: write the animation.
    Returns:
        JSON-ready summary (also written to ``rollout.json``; table in ``rollout.md``).
    """
    from thrombojax.errors import DatasetError
    from thrombojax.io.hdf5 import open_dataset
    from thrombojax.train.state import load_trained

    trained = load_trained(run_dir, which=which)
    ds = open_dataset(dataset_path)
    check_units(trained.config, ds, run_dir=run_dir, dataset_path=dataset_path)
    names = list(simulations) if simulations else split_names(trained.config, ds.names, split)
    missing = [n for n in names if n not in ds.names]
    if missing:
        raise DatasetError(f"{dataset_path}: no simulation(s) {missing}; have {list(ds.names)}")
    skip = default_skip(ds) if skip is None else int(skip)
    n_nodes = n_nodes or config_value(trained.config, "nodes_per_sample", default=None)
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    report, rows = {}, []
    for name in names:
        sim = ds[name]
        pos, node_type = scaled_simulation(ds, name, trained.scaling)
        res = rollout_simulation(trained.model, trained.params, trained.stats, pos, node_type,
                                 name=name, t0=max(skip, 1), n_steps=n_steps, n_nodes=n_nodes,
                                 seed=seed, wall_cells=sim.wall_cells)
        files = save_rollout(res, sim, trained.scaling, out_dir,
                             model_name=trained.model.name, format=format, gif=gif,
                             units=str(ds.attrs.get("units", "")))
        report[name] = {"t0": res.t0, "n_steps": int(res.pred.shape[0]),
                        "n_nodes": int(res.node_index.size), "summary": res.summary,
                        "files": files, "node_index": res.node_index.tolist(),
                        "curves": {k: {m: v.tolist() for m, v in c.items()}
                                   for k, c in res.curves.items()}}
        for label, s in res.summary.items():
            if label != "ground truth":
                rows.append([name, label, s.get("mse@1", "n/a"), s.get("mse@10", "n/a"),
                             s.get("mse@50", "n/a"), s["mse@full"], s["final_centroid_error"],
                             s["max_fraction_outside"]])
    result = {"model": trained.model.name, "run_dir": str(run_dir), "dataset": str(dataset_path),
              "skip": skip, "seed": seed, "units": str(ds.attrs.get("units", "")),
              "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
              "simulations": report}
    (out_dir / "rollout.json").write_text(json.dumps(result, indent=1))
    table = markdown_table(["simulation", "model", "MSE@1", "MSE@10", "MSE@50", "MSE@full",
                            "final centroid err", "max frac. outside"], rows)
    (out_dir / "rollout.md").write_text(
        "# Rollout errors (clot nodes, scaled coordinates; mean over the first h steps)\n\n"
        f"Dataset length unit: {result['units'] or 'not recorded'} (pictures and ParaView "
        "files are in this unit).\n\n" + table)
    result["table"] = table
    return result
