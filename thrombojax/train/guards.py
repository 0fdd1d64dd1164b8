"""Guards against silent wrong results when a run meets a dataset.

- :func:`dataset_fingerprint` / :func:`check_resume_dataset`: ``train --resume`` continues a run
  only on the dataset it started with (names, shapes, node types, first / last frames, scaling).
- :func:`check_split_names`: ``evaluate`` / ``rollout`` refuse an empty split or a dataset that
  lacks the run's simulations, naming them.
- :func:`check_in_box`: data far outside the run's scaling box (a different unit, another
  dataset) is refused; slightly outside gives a warning.
- :func:`check_finite`: a non-finite validation metric or result is an error, never a
  checkpoint or a table.
"""

from __future__ import annotations

import hashlib
import math
import pathlib
import warnings
from collections.abc import Iterable, Mapping
from typing import Any

import jax
import numpy as np

from thrombojax.errors import ConfigError, DatasetError, ThrombojaxError

__all__ = [
    "BOX_WARN",
    "BOX_REFUSE",
    "dataset_fingerprint",
    "check_resume_dataset",
    "check_split_names",
    "check_in_box",
    "check_finite",
    "NonFiniteError",
    "clear_run",
    "warn_schedule",
    "warn_large_cpu_cases",
]

BOX_WARN = 1.25  # |scaled coordinate| above this: warning (the run's data lies in [-1, 1])
BOX_REFUSE = 3.0  # above this: the data is not what the run was trained on


class NonFiniteError(ThrombojaxError, FloatingPointError):
    """A metric or a prediction became NaN or infinite."""


def dataset_fingerprint(ds: Any) -> dict:
    """Names, ``[T, N]`` shapes and a hash of node types and first / last frames of a Dataset.

    Reads two frames and the node types per simulation, so it is cheap on large files.
    """
    h = hashlib.sha256()
    shapes = {}
    for name in ds.names:
        t, n = ds.n_frames(name), ds.n_nodes(name)
        shapes[name] = [int(t), int(n)]
        h.update(name.encode("utf-8", "surrogatepass"))
        h.update(np.ascontiguousarray(ds.node_type(name)).tobytes())
        h.update(np.ascontiguousarray(ds.positions(name, [0, t - 1])).tobytes())
    return {"names": list(ds.names), "shapes": shapes, "sha256": h.hexdigest()}


def check_resume_dataset(saved: Mapping, current_fp: dict, current_scaling: dict,
                         dataset_path: Any, run_dir: Any) -> None:
    """Refuse to resume ``run_dir`` on a dataset other than the one it started with.

    Args:
        saved: the run's ``config.json``.
        current_fp: :func:`dataset_fingerprint` of the dataset given now.
        current_scaling: its fitted scaling (``Scaling.to_dict()``).
    Raises:
        ConfigError: naming the first difference (simulations, shapes, content, scaling).
    """
    def fail(what: str) -> ConfigError:
        return ConfigError(f"{run_dir}: --resume with dataset {dataset_path}, which differs from "
                           f"the run's dataset {saved.get('dataset', '?')}: {what}; resume with "
                           "the original dataset or train a new run")

    old = saved.get("dataset_fingerprint")
    if isinstance(old, dict):
        if old.get("names") != current_fp["names"]:
            gone = sorted(set(old.get("names", [])) ^ set(current_fp["names"]))
            raise fail(f"simulations differ ({gone[:5]})")
        for name, shape in current_fp["shapes"].items():
            if old.get("shapes", {}).get(name) != shape:
                raise fail(f"simulation '{name}' has shape [frames, nodes] {shape}, "
                           f"was {old.get('shapes', {}).get(name)}")
        if old.get("sha256") != current_fp["sha256"]:
            raise fail("same names and shapes, different positions or node types")
    split = saved.get("split", {})
    used = [n for part in ("train", "val", "test") for n in split.get(part, [])]
    missing = [n for n in used if n not in current_fp["names"]]
    if missing:
        raise fail(f"simulation(s) {missing[:5]} of the run's split are missing")
    old_scaling = saved.get("scaling")
    if isinstance(old_scaling, dict):
        for key in ("center", "scale"):
            a, b = np.asarray(old_scaling.get(key), float), np.asarray(current_scaling.get(key),
                                                                        float)
            if a.shape != b.shape or not np.allclose(a, b, rtol=1e-6, atol=1e-9):
                raise fail(f"scaling '{key}' {b.tolist()} != the run's {a.tolist()}")


def check_split_names(names: list[str], available: Iterable[str], split: str, dataset_path: Any,
                      run_dir: Any) -> None:
    """Refuse an empty selection, or names the dataset does not hold (one line, named)."""
    available = list(available)
    if not names:
        raise ConfigError(f"{run_dir}: the run's '{split}' split is empty (trained with "
                          f"--n-{split} 0?); choose --split all or another split")
    missing = [n for n in names if n not in available]
    if missing:
        origin = ("asked for with --sim" if split == "--sim"
                  else f"of the run {run_dir}'s '{split}' split (a different dataset?)")
        raise DatasetError(f"{dataset_path}: has no simulation(s) {missing[:5]} {origin}; "
                           f"available: {available[:8]}")


def check_in_box(pos: np.ndarray, name: str, dataset_path: Any, run_dir: Any) -> None:
    """Refuse (or warn about) scaled positions far outside the run's [-1, 1] box.

    Args:
        pos: scaled positions of one simulation.
    Raises:
        DatasetError: ``max |pos| > BOX_REFUSE`` (naming the simulation and the factor).
    """
    reach = float(np.max(np.abs(pos))) if np.size(pos) else 0.0
    if reach > BOX_REFUSE:
        raise DatasetError(
            f"{dataset_path}: simulation '{name}': field 'positions': reaches {reach:.3g} in the "
            f"run {run_dir}'s scaled coordinates (its training data lies in [-1, 1]); other "
            "units or another geometry? Results would be meaningless"
        )
    if reach > BOX_WARN:
        warnings.warn(
            f"{dataset_path}: simulation '{name}' reaches {reach:.3g} in the run's scaled "
            "coordinates, outside the training box [-1, 1]: errors may be large",
            stacklevel=2,
        )


def check_finite(values: Mapping[str, Any], where: str) -> None:
    """Raise :class:`NonFiniteError` naming the first NaN / infinite value of ``values``."""
    for key, value in values.items():
        if isinstance(value, int | float | np.floating) and not math.isfinite(float(value)):
            raise NonFiniteError(f"{where}: {key} is {value}")


RUN_FILES = ("config.json", "metrics.jsonl", "loss.png")


def clear_run(run_dir: Any) -> None:
    """Remove a previous run's files from ``run_dir`` (``train --force``): its checkpoints,
    ``config.json``, ``metrics.jsonl`` and ``loss.png``; nothing else in the folder.

    The checkpoints folder goes with :func:`thrombojax.io.outputs.remove_atomically`: a process
    killed while deleting leaves a temporary that the next run removes, never a half-deleted
    checkpoint at the path a loader reads (``tests/test_kill_trials_train.py``)."""
    from thrombojax.io.outputs import remove_atomically

    run_dir = pathlib.Path(run_dir)
    remove_atomically(run_dir / "checkpoints")
    for name in RUN_FILES:
        (run_dir / name).unlink(missing_ok=True)


def warn_schedule(epochs: int, warmup_epochs: float) -> None:
    """Warn when the linear warm-up covers the whole run (the peak rate is never reached)."""
    if warmup_epochs >= epochs:
        warnings.warn(f"--warmup-epochs {warmup_epochs:g} >= --epochs {epochs}: the learning "
                      "rate warms up for the whole run and never reaches its peak", stacklevel=2)


LARGE_CPU_NODES = 10_000


def warn_large_cpu_cases(cases: Iterable[str], n_nodes: int | None, table: Mapping) -> None:
    """Warn before timing cases of ``LARGE_CPU_NODES`` nodes or more on a CPU (minutes each)."""
    if jax.default_backend() != "cpu":
        return
    big = [c for c in cases if c in table and (n_nodes or table[c].n_nodes) >= LARGE_CPU_NODES]
    if big:
        warnings.warn(f"bench: timing {big} ({n_nodes or table[big[0]].n_nodes:,} nodes) on a "
                      "CPU takes minutes per model; pass --cases bendvessel,clotentry or "
                      "--nodes to skip or shrink them", stacklevel=2)
