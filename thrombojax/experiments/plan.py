"""The run list of an experiment at one scale, its sharding over workers and its cost estimate.

Runs are listed in a fixed order (dataset, model, value, seed), so every process computes the
same list and ``--worker i/n`` (:func:`shard`) takes every n-th run from the i-th: the shards of
``0/n .. n-1/n`` partition the list, whatever the machine.

The cost estimate (:func:`estimate`) is ``sum over runs of epochs x steps_per_epoch x step_s``:
``steps_per_epoch = ceil(train_windows x (1 + bary_ratio) / batch_size)`` as the training loop
plans its epochs (``thrombojax/data/batching.py``, ``epoch_plan``), ``train_windows`` from the
preset's simulations and frames (``thrombojax/sim/presets.py``) and the split, and ``step_s``
the seconds per step each experiment file records per model with its source.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

from thrombojax.errors import ConfigError
from thrombojax.experiments.spec import Experiment, Scale
from thrombojax.io.outputs import safe_stem
from thrombojax.sim.presets import get_preset
from thrombojax.study import training_defaults
from thrombojax.train.config import TrainConfig

__all__ = ["Run", "plan_runs", "parse_worker", "shard", "value_label", "estimate",
           "train_windows"]


@dataclasses.dataclass(frozen=True)
class Run:
    """One training run (or one timing) of an experiment.

    Attributes:
        key: its folder name under ``DIR/runs`` (unique within the experiment).
        dataset: solver preset of its dataset. model: registry name. seed: training seed.
        value: the sweep value, the ladder rung (a dict) or ``None``. label: ``value`` in words.
        train: the training config (sweep value and seed applied; a generalisation's split
            by rotation is applied once the dataset exists).
    """

    key: str
    dataset: str
    model: str
    seed: int
    value: Any
    label: str
    train: TrainConfig


def value_label(value: Any) -> str:
    """A short label of a sweep value or rung: ``pi/2``, ``0.5``, ``noise``."""
    if isinstance(value, dict):
        return str(value.get("name", "rung"))
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _key(*parts: Any) -> str:
    text = "__".join(re.sub(r"[^A-Za-z0-9_.-]", "-", str(p)) for p in parts if p != "")
    return safe_stem(text)


def _rung_train(value: Any, where: str) -> dict:
    if not isinstance(value, dict) or "name" not in value:
        raise ConfigError(f"{where}: a ladder rung is a table with 'name', 'train', 'guards'")
    train = value.get("train", {})
    if not isinstance(train, dict):
        raise ConfigError(f"{where}: rung '{value['name']}': 'train' must be a table")
    return train


def plan_runs(experiment: Experiment, scale_name: str, seeds: tuple[int, ...] | None = None
              ) -> list[Run]:
    """Every run of ``experiment`` at ``scale_name``, in the fixed order.

    Args:
        seeds: replace the scale's seeds (``--seeds``).
    """
    scale = experiment.scale(scale_name)
    seeds = tuple(seeds) if seeds else scale.seeds
    where = f"{experiment.path}: [{scale_name}]"
    runs = []
    if experiment.kind == "timing":  # one timing per model, no training, no seeds
        for model in scale.models:
            runs.append(Run(_key(model), scale.datasets[0] if scale.datasets else "", model, 0,
                            None, "", scale.train))
        return runs
    prefix = experiment.sweep or {"generalisation": "train_deg", "ladder": "rung"}.get(
        experiment.kind, "v")
    values = scale.values if experiment.kind in ("sweep", "generalisation", "ladder") else (None,)
    for dataset in scale.datasets:
        for model in scale.models:
            for value in values:
                label = value_label(value) if value is not None else ""
                for seed in seeds:
                    changes: dict = {**scale.per_dataset.get(dataset, {}), "seed": seed,
                                     "model_config": {
                        **scale.train.model_config, **scale.model_config.get(model, {})}}
                    if experiment.kind == "sweep":
                        changes[experiment.sweep] = value
                    elif experiment.kind == "ladder":
                        changes.update(_rung_train(value, where))
                    try:
                        cfg = scale.train.replace(**changes)
                    except (ConfigError, TypeError) as err:
                        raise ConfigError(f"{where}: value {label!r}: {err}") from err
                    key = _key(dataset, model, f"{prefix}={label}" if label else "",
                               f"s{seed}")
                    runs.append(Run(key, dataset, model, seed, value, label, cfg))
    keys = [r.key for r in runs]
    if len(set(keys)) != len(keys):
        raise ConfigError(f"{where}: two runs share a folder name; make the values distinct")
    return runs


def parse_worker(text: str | None) -> tuple[int, int]:
    """``"i/n"`` -> ``(i, n)`` with ``0 <= i < n`` (``None``: ``(0, 1)``, every run)."""
    if text is None:
        return 0, 1
    match = re.fullmatch(r"\s*(\d+)\s*/\s*(\d+)\s*", str(text))
    if not match:
        raise ConfigError(f"--worker expects i/n (e.g. 0/4), got '{text}'")
    i, n = int(match.group(1)), int(match.group(2))
    if n < 1 or not 0 <= i < n:
        raise ConfigError(f"--worker {text}: need 0 <= i < n")
    return i, n


def shard(runs: list[Run], worker: tuple[int, int]) -> list[Run]:
    """The runs of worker ``i`` of ``n``: runs ``i, i + n, i + 2n, ...`` of the fixed list."""
    i, n = worker
    return runs[i::n]


def train_windows(run: Run, kind: str = "sweep") -> int:
    """Real training windows of a run, from its preset's shape and its split (a
    generalisation trains on the simulations rotated by at most its value, in degrees)."""
    preset = get_preset(run.dataset)
    cfg = run.train
    if kind == "generalisation" and preset.kind == "bend":
        n_train = int(float(run.value) // preset.rotation_step_deg) + 1
    elif cfg.train_sims or cfg.val_sims or cfg.test_sims:  # a split by name
        n_train = len(cfg.train_sims) or preset.n_sims - len(cfg.val_sims) - len(cfg.test_sims)
    else:
        n_train = max(preset.n_sims - cfg.n_val - cfg.n_test, 1)
    length = cfg.window_length
    per_sim = max(preset.n_frames + 1 - length + 1 - cfg.skip_frames, 0)
    return n_train * per_sim


def _run_steps(run: Run, kind: str) -> int:
    cfg = run.train
    batch = cfg.batch_size or int(training_defaults(run.model)["batch_size"])
    return cfg.epochs * math.ceil(train_windows(run, kind) * (1.0 + cfg.bary_ratio) / batch)


def estimate(experiment: Experiment, scale_name: str) -> dict:
    """The cost of a scale: runs, training steps, and seconds where ``step_s`` is known.

    Returns:
        ``{"runs", "steps", "seconds" (None when a model's step time is unknown), "how"}``.
    """
    scale: Scale = experiment.scale(scale_name)
    runs = plan_runs(experiment, scale_name)
    if experiment.kind == "timing":
        return {"runs": len(runs), "steps": 0, "seconds": None,
                "how": "no training: compile and time rollouts of each model"}
    count = len(runs)
    if experiment.kind == "search":
        trials = int(scale.options.get("trials", 1))
        count = trials * len(runs)
    steps = sum(_run_steps(r, experiment.kind) for r in runs) * (count // max(len(runs), 1))
    known = all(r.model in scale.step_s for r in runs)
    seconds = (sum(_run_steps(r, experiment.kind) * scale.step_s[r.model] for r in runs)
               * (count // max(len(runs), 1)) if known else None)
    how = (f"training only (not evaluation, not dataset generation): {count} runs x epochs x "
           f"ceil(train windows x (1 + bary_ratio) / batch) steps x step_s "
           f"({scale.step_s_source or 'source not recorded'})")
    return {"runs": count, "steps": steps, "seconds": seconds, "how": how}
