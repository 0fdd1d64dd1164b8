"""Writing the dataset file: atomic, streaming, validated (the layout: ``docs/dataset.md``).

Writing goes to a temporary file beside the target that is renamed onto it only when the
writer exits cleanly, so an exception never leaves a partial file at the target. The reader
is :mod:`thrombojax.io.hdf5`.
"""

from __future__ import annotations

import datetime
import os
from collections.abc import Iterable
from pathlib import Path

import h5py
import numpy as np
from tqdm import tqdm

from thrombojax.errors import DatasetError
from thrombojax.io.outputs import check_target, temp_path
from thrombojax.io.schema import (
    VESSEL_TOLERANCE,
    Simulation,
    encode_attrs,
    simulation_error,
    to_json,
    validate_simulation,
)
from thrombojax.study import UNKNOWN_KIND

__all__ = ["FORMAT", "VERSION", "DatasetWriter", "write_dataset"]


FORMAT = "thrombojax.dataset"
VERSION = 1
_CELLS = {"clot_cells": 4, "wall_cells": 3}


class DatasetWriter:
    """Stream simulations into a new dataset file, atomically.

    Use as a context manager; each :meth:`add` validates and writes one simulation, so only
    one simulation is in memory at a time. The file appears at ``path`` only when the ``with``
    block exits without an exception (temporary file + rename); otherwise nothing is left.

    Args:
        path: target ``.h5`` file (parent folders are created).
        name: dataset name (file attribute).
        source: solver name or import origin (file attribute).
        units: unit of the positions (file attribute).
        generator_config: JSON-serialisable preset of the generator, when generated.
        kind: which of the study's datasets this is like (``bendvessel``, ``clotentry``) or
            ``unknown`` (file attribute, :func:`thrombojax.study.dataset_kind`).
        skip_frames: leading frames rollouts skip on this dataset (file attribute,
            :func:`thrombojax.study.skip_frames`).
        overwrite, inputs: replace an existing file at ``path`` (else OutputError); ``path`` is
            never one of ``inputs``, the files the dataset is made from.
        vessel_tol: relative tolerance of the vessel-rigidity check.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        *,
        name: str,
        source: str,
        units: str = "vessel radius",
        generator_config: dict | None = None,
        kind: str = UNKNOWN_KIND,
        skip_frames: int = 0,
        overwrite: bool = True,
        inputs: Iterable[str | os.PathLike] = (),
        vessel_tol: float = VESSEL_TOLERANCE,
    ):
        self.path = Path(path)
        if isinstance(skip_frames, bool) or not isinstance(skip_frames, int) or skip_frames < 0:
            raise simulation_error(self.path, None, "skip_frames",
                                   f"must be an integer >= 0, got {skip_frames!r}")
        self._file_attrs = {
            "format": FORMAT,
            "version": VERSION,
            "name": str(name),
            "source": str(source),
            "units": str(units),
            "kind": str(kind),
            "skip_frames": int(skip_frames),
        }
        try:
            self._file_attrs["generator_config"] = to_json(generator_config)
        except (TypeError, ValueError) as err:
            raise simulation_error(self.path, None, "generator_config", str(err)) from err
        self._overwrite, self._inputs = overwrite, tuple(inputs)
        self._vessel_tol = vessel_tol
        self._tmp: Path | None = None
        self._h5: h5py.File | None = None
        self.names: list[str] = []

    def _check_target(self) -> None:
        check_target(self.path, inputs=self._inputs, force=self._overwrite, what="dataset")

    def __enter__(self) -> DatasetWriter:
        self._check_target()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = temp_path(self.path, ".tmp")  # also removes dead processes' temporaries
        self._h5 = h5py.File(self._tmp, "w")
        created = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
        self._h5.attrs.update({**self._file_attrs, "created": created})
        self._h5.create_group("simulations")
        return self

    def add(self, sim: Simulation) -> None:
        """Validate one simulation and write it to the file.

        Args:
            sim: positions ``[T, N, 3]`` (cast to float32), node_type ``[N]`` (cast to int8).
        Raises:
            DatasetError: the simulation is invalid or its name is already in the file.
        """
        if self._h5 is None:
            raise DatasetError(f"{self.path}: DatasetWriter.add outside its 'with' block")
        validate_simulation(sim, path=self.path, vessel_tol=self._vessel_tol)
        if sim.name in self.names:
            raise simulation_error(self.path, sim.name, "name", "duplicate simulation name "
                                   "(names must be unique; give them explicitly)")
        positions = sim.positions.astype(np.float32, copy=False)
        if not np.isfinite(positions).all():
            raise simulation_error(self.path, sim.name, "positions", "overflows float32")
        group = self._h5["simulations"].create_group(sim.name)
        group.create_dataset("positions", data=positions)
        group.create_dataset("node_type", data=sim.node_type.astype(np.int8))
        for field in _CELLS:
            cells = getattr(sim, field)
            if cells is not None:
                group.create_dataset(field, data=cells.astype(np.int32))
        try:
            encode_attrs(group.attrs, sim.attrs)
        except (TypeError, ValueError, OSError, RuntimeError) as err:
            raise simulation_error(self.path, sim.name, "attrs", f"cannot store: {err}") from err
        self._h5.flush()
        self.names.append(sim.name)

    def __exit__(self, exc_type, exc, tb) -> None:
        h5, tmp = self._h5, self._tmp
        self._h5 = None
        if h5 is None or tmp is None:
            return
        h5.close()
        try:
            if exc_type is not None:
                return
            if not self.names:
                raise DatasetError(f"{self.path}: no simulations were added; nothing written")
            self._check_target()
            with open(tmp, "rb+") as f:  # on disk before the rename makes it visible
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
        finally:
            tmp.unlink(missing_ok=True)


def write_dataset(
    path: str | os.PathLike,
    simulations: Iterable[Simulation],
    *,
    name: str,
    source: str,
    units: str = "vessel radius",
    generator_config: dict | None = None,
    kind: str = UNKNOWN_KIND,
    skip_frames: int = 0,
    overwrite: bool = True,
    inputs: Iterable[str | os.PathLike] = (),
    progress: bool = False,
) -> Path:
    """Write simulations (any iterable, consumed one at a time) to ``path`` atomically.

    Returns:
        The path written. Arguments as for :class:`DatasetWriter`.
    """
    writer = DatasetWriter(path, name=name, source=source, units=units,
                           generator_config=generator_config, kind=kind,
                           skip_frames=skip_frames, overwrite=overwrite, inputs=inputs)
    with writer:
        for sim in tqdm(simulations, desc="writing", unit="sim", disable=not progress):
            writer.add(sim)
    return writer.path
