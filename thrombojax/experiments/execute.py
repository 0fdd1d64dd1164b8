"""One run of an experiment: train (or resume), measure, and record ``result.json``.

A run folder ``DIR/runs/<key>/`` is an ordinary training run (``config.json``, ``checkpoints``,
``metrics.jsonl``, ``loss.png``, ``tensorboard/``) plus:

* ``spec.json``: what the run is (experiment, scale, dataset, model, value, training config),
  written before training; a restart with other settings is refused unless ``--force``.
* the measurement of the experiment's kind: ``evaluate.json`` (single-step test MSE,
  ``thrombojax/eval/single_step.py``), ``rollout/`` or ``rollout_guards/`` (rollouts,
  ``thrombojax/eval/report.py``), ``bench.json`` (timing, ``thrombojax/eval/bench.py``);
* ``result.json``: the numbers the report aggregates, written last. A run with a
  ``result.json`` matching its spec is finished and never redone; a run killed during training
  resumes from its last checkpoint (bit for bit, ``thrombojax/train/loop.py``).
"""

from __future__ import annotations

import datetime
import json
import pathlib
from collections.abc import Callable
from typing import Any

import numpy as np

from thrombojax.errors import ConfigError, OutputError
from thrombojax.eval.bench import bench
from thrombojax.eval.physical import CV_LABEL
from thrombojax.eval.report import rollout_run
from thrombojax.eval.single_step import evaluate_run
from thrombojax.experiments.plan import Run
from thrombojax.experiments.tensorboard import TENSORBOARD_NOTE, tensorboard_logger
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text
from thrombojax.train.config import TrainConfig
from thrombojax.train.loop import train
from thrombojax.train.state import latest_step

__all__ = ["run_folder", "run_spec", "read_result", "execute_run", "rotation_split",
           "train_run"]


def run_folder(out: str | pathlib.Path, run: Run) -> pathlib.Path:
    """``DIR/runs/<key>``."""
    return pathlib.Path(out) / "runs" / run.key


def run_spec(experiment: str, scale: str, run: Run, options: dict) -> dict:
    """The JSON-ready identity of a run (compared on restart)."""
    return {"experiment": experiment, "scale": scale, "key": run.key, "dataset": run.dataset,
            "model": run.model, "seed": run.seed, "value": run.value, "label": run.label,
            "train": run.train.to_dict(), "options": options}


def read_result(folder: pathlib.Path) -> dict | None:
    """A finished run's ``result.json``, else ``None``."""
    path = folder / "result.json"
    return json.loads(path.read_text()) if path.is_file() else None


def _same(a: Any, b: Any) -> bool:
    return json.loads(json.dumps(a)) == json.loads(json.dumps(b))


def rotation_split(dataset_path: str | pathlib.Path, max_deg: float) -> dict:
    """The generalisation split: test on the simulation with the largest rotation, train on
    those rotated by at most ``max_deg`` degrees (no validation: the best checkpoint is the
    lowest training MSE). Rotations are the ``rotation_deg`` simulation attributes the
    solver's bend presets record (``thrombojax/sim/cases.py``)."""
    ds = open_dataset(dataset_path)
    rot = {}
    for name in ds.names:
        attrs = ds[name].attrs
        if "rotation_deg" not in attrs:
            raise ConfigError(f"{dataset_path}: simulation '{name}' has no rotation_deg "
                              "attribute; a generalisation over rotations needs them")
        rot[name] = float(attrs["rotation_deg"])
    test = max(rot, key=rot.get)
    train_sims = [n for n, r in rot.items() if r <= float(max_deg) and n != test]
    if not train_sims:
        raise ConfigError(f"{dataset_path}: no simulation rotated by <= {max_deg} degrees")
    return {"train_sims": train_sims, "val_sims": [], "test_sims": [test],
            "test_rotation_deg": rot[test]}


def train_run(run: Run, cfg: TrainConfig, folder: pathlib.Path, data: pathlib.Path, *,
              force: bool, progress: bool,
              callback: Callable[[int, dict], None] | None = None) -> str:
    """Train (or resume) one run in ``folder``; returns the TensorBoard note ("" when
    written)."""
    resume = not force and latest_step(folder / "checkpoints" / "last") is not None
    tb, close = tensorboard_logger(folder, resume=resume)

    def both(step: int, metrics: dict) -> None:
        if tb is not None:
            tb(step, metrics)
        if callback is not None:
            callback(step, metrics)

    try:
        if resume:
            train(data, run.model, folder, resume=True, progress=progress, callback=both)
        else:
            train(data, run.model, folder, config=cfg, progress=progress, callback=both,
                  force=force)
    finally:
        close()
    return "" if tb is not None else TENSORBOARD_NOTE


def _curve(rollout: dict, guards: bool) -> dict:
    """Mean per-step MSE (vessel radii squared) of the model and CV over the rolled out
    simulations, with the rollout-phase single-step MSE."""
    sims = list(rollout["simulations"].values())
    label = rollout["model"]
    model = np.mean([s["curves"][label]["rmse_r"] for s in sims], axis=0) ** 2
    cv = np.mean([s["curves"][CV_LABEL]["rmse_r"] for s in sims], axis=0) ** 2
    return {"mse_per_step_r2": model.tolist(), "cv_mse_per_step_r2": cv.tolist(),
            "mse_full_r2": float(model.mean()), "cv_mse_full_r2": float(cv.mean()),
            "mse10_r2": float(model[:10].mean()), "guards": guards}


def _measure(kind: str, folder: pathlib.Path, data: pathlib.Path, run: Run,
             options: dict) -> dict:
    if kind in ("sweep", "seeds", "generalisation"):
        ev = evaluate_run(folder, data, out_dir=folder, progress=False, force=True)
        return {"mse": ev["mse"], "mse_r2": ev["mse_r2"],
                "cv_mse": ev["constant_velocity_mse"], "test_sims": ev["selection"]["simulations"]}
    if kind == "rollout":
        ev = evaluate_run(folder, data, out_dir=folder, progress=False, force=True)
        guards = bool(options.get("guards", False))
        ro = rollout_run(folder, data, folder / "rollout", gif=False, force=True,
                         guards=guards, n_steps=options.get("rollout_steps"))
        return {"mse": ev["mse"], "cv_mse": ev["constant_velocity_mse"],
                "rollout": _curve(ro, guards)}
    if kind == "ladder":
        ev = evaluate_run(folder, data, out_dir=folder, progress=False, force=True)
        out = {"mse": ev["mse"], "cv_mse": ev["constant_velocity_mse"], "rollouts": {}}
        for guards in run.value.get("guards", [False]):
            name = "rollout_guards" if guards else "rollout"
            ro = rollout_run(folder, data, folder / name, gif=False, force=True,
                             guards=bool(guards), n_steps=options.get("rollout_steps"))
            out["rollouts"][name] = _curve(ro, bool(guards))
        return out
    raise ConfigError(f"experiment kind '{kind}' has no run measurement")


def execute_run(experiment: str, kind: str, scale: str, run: Run, out: str | pathlib.Path,
                data: pathlib.Path | None, options: dict, *, force: bool = False,
                progress: bool = False) -> dict:
    """Run one run unless it is finished; returns its result.

    Args:
        experiment, kind, scale: the experiment's name and kind, the scale's name.
        run: the run. out: the experiment folder. data: its dataset file (timing: may be None).
        options: the scale's kind-specific options.
        force: redo the run even if finished (its training starts afresh).
        progress: progress bars.
    Raises:
        OutputError: the run folder holds a run of other settings (and not ``force``).
    """
    folder = run_folder(out, run)
    spec = run_spec(experiment, scale, run, options)
    spec_path = folder / "spec.json"
    if spec_path.is_file() and not force:
        saved = json.loads(spec_path.read_text())
        if not _same(saved, spec):
            changed = sorted(k for k in spec if not _same(saved.get(k), spec[k]))
            raise OutputError(f"{folder}: holds this run with other settings ({changed}); "
                              "use another --out, or --force to redo it")
        done = read_result(folder)
        if done is not None:
            return done
    folder.mkdir(parents=True, exist_ok=True)
    if force and (folder / "result.json").is_file():
        (folder / "result.json").unlink()
    atomic_write_text(spec_path, json.dumps(spec, indent=2))
    note = ""
    if kind == "timing":
        b = options.get("bench", {})
        metrics = bench((run.model,), tuple(b.get("cases", ("bendvessel",))),
                        tiny=bool(b.get("tiny", False)), max_steps=b.get("max_steps"),
                        repeats=int(b.get("repeats", 3)),
                        solver_datasets=(str(data),) if data else (), out_dir=folder,
                        progress=progress, force=True)
        metrics = {"bench": metrics["results"]}
    else:
        cfg = run.train
        if kind == "generalisation":
            split = rotation_split(data, float(run.value))
            cfg = cfg.replace(**{k: split[k] for k in ("train_sims", "val_sims", "test_sims")})
        note = train_run(run, cfg, folder, data, force=force, progress=progress)
        metrics = _measure(kind, folder, data, run, options)
        if kind == "generalisation":
            metrics["test_rotation_deg"] = split["test_rotation_deg"]
    result = {**spec, "metrics": metrics, "tensorboard_note": note,
              "finished": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")}
    atomic_write_text(folder / "result.json", json.dumps(result, indent=1))
    return result
