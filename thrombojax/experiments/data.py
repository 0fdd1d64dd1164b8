"""Datasets of an experiment: generated on demand with the built-in solver, cached by preset.

``DIR/data/<preset>.h5`` (or ``--data-dir``) holds each preset's dataset once generated; later
runs, restarts and other experiments with the same data folder reuse it. A dataset file can
also be named explicitly (``--dataset PRESET=FILE``, e.g. an import of the study's Abaqus data
made with ``thrombojax import``), and is then only read.
"""

from __future__ import annotations

import os
import pathlib
from collections.abc import Mapping

from thrombojax.errors import ConfigError
from thrombojax.io.outputs import temp_path
from thrombojax.sim.generate import generate_dataset
from thrombojax.sim.presets import get_preset

__all__ = ["dataset_path", "ensure_dataset", "parse_dataset_overrides"]


def dataset_path(preset: str, data_dir: str | pathlib.Path) -> pathlib.Path:
    """Where the cached dataset of ``preset`` lives in ``data_dir``."""
    get_preset(preset)  # unknown presets fail here, naming the known ones
    return pathlib.Path(data_dir) / f"{preset}.h5"


def ensure_dataset(preset: str, data_dir: str | pathlib.Path, *,
                   given: Mapping[str, str] | None = None, progress: bool = False) -> pathlib.Path:
    """The dataset of ``preset``: a given file, the cached one, or a newly generated one.

    Generation writes a temporary file beside the target and renames it, so a killed run leaves
    no partial dataset and two workers generating the same preset at once both end with the
    same complete file (generation is deterministic for a preset and seed 0).
    """
    if given and preset in given:
        path = pathlib.Path(given[preset])
        if not path.is_file():
            raise FileNotFoundError(f"{path}: dataset given for '{preset}' not found")
        return path
    target = dataset_path(preset, data_dir)
    if target.is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_path(target)
    try:
        generate_dataset(preset, tmp, progress=progress)
        os.replace(tmp, target)
    finally:
        if tmp.exists():
            tmp.unlink()
    return target


def parse_dataset_overrides(items: list[str] | None) -> dict[str, str]:
    """``["bendvessel=data/bv.h5"]`` -> ``{"bendvessel": "data/bv.h5"}`` (``--dataset``)."""
    out = {}
    for item in items or []:
        preset, sep, path = item.partition("=")
        if not sep or not preset or not path:
            raise ConfigError(f"--dataset expects PRESET=FILE, got '{item}'")
        get_preset(preset)
        out[preset] = path
    return out
