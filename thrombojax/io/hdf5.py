"""The dataset file: lazy read and validation (writing: :mod:`thrombojax.io.writer`).

Layout (``docs/dataset.md``)::

    /                       attrs: format="thrombojax.dataset", version, name, source, units,
                                   kind (bendvessel / clotentry / unknown), skip_frames,
                                   created (ISO 8601 UTC), generator_config (JSON, "null" if none)
    /simulations/<name>/    positions  float32 [T, N, 3]   (physical units, contiguous)
                            node_type  int8    [N]         (NodeType: 0 vessel, 1 clot)
                            clot_cells int32   [C, 4]      (optional, tetrahedra)
                            wall_cells int32   [F, 3]      (optional, triangles)
                            attrs: dt, solver_wall_time_s, reference_wall_time_s, rotation_deg,
                                   seed, ... (lists / dicts / None as JSON, their names listed
                                   in the attribute "_json_attrs")

Reading opens
the file per call and reads only what is asked for (a ClotEntry-size dataset is ~650 MB).
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from tqdm import tqdm

from thrombojax.errors import DatasetError
from thrombojax.io.schema import (
    KNOWN_NODE_TYPES,
    Simulation,
    check_positions_shape,
    check_stored_size,
    decode_attrs,
    natural_key,
    simulation_error,
    validate_simulation,
)
from thrombojax.io.writer import _CELLS, FORMAT, VERSION, DatasetWriter, write_dataset
from thrombojax.types import NodeType

__all__ = [
    "FORMAT",
    "VERSION",
    "Simulation",
    "Dataset",
    "DatasetWriter",
    "write_dataset",
    "open_dataset",
    "validate_simulation",
]

class Dataset(Mapping[str, Simulation]):
    """A lazily read dataset file: a mapping ``name -> Simulation`` read on access.

    Opening checks the file attributes and every simulation's structure (fields, shapes,
    dtypes) from metadata only; ``ds[name]`` reads one simulation and validates its values.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        if not self.path.exists():
            raise FileNotFoundError(f"{self.path}: no such file")
        if self.path.is_dir():
            raise IsADirectoryError(f"{self.path}: is a directory, expected an .h5 dataset file")
        with self._open() as h5:
            self.attrs = self._read_file_attrs(h5)
        with self._open(None, "simulations") as h5:
            group = h5.get("simulations")
            if not isinstance(group, h5py.Group):
                raise simulation_error(self.path, None, "simulations", "missing group")
            self.names: list[str] = sorted(group.keys(), key=natural_key)
        if not self.names:
            raise simulation_error(self.path, None, "simulations", "no simulations in file")
        self._shapes: dict[str, tuple[int, int]] = {}
        for name in self.names:
            with self._open(name, "structure") as h5:
                self._shapes[name] = self._check_structure(h5["simulations"], name)

    @contextlib.contextmanager
    def _open(self, sim: str | None = None, field: str | None = None) -> Iterator[h5py.File]:
        """Open the file read-only, turning h5py failures into named DatasetErrors."""
        try:
            with h5py.File(self.path, "r") as h5:
                yield h5
        except DatasetError:
            raise
        except (OSError, KeyError, RuntimeError, ValueError) as err:
            if isinstance(err, FileNotFoundError) and not self.path.exists():
                raise FileNotFoundError(f"{self.path}: no such file") from err
            if sim is None and field is None:
                what = f"not a readable HDF5 file ({err})"
            else:
                what = f"missing or unreadable ({err})"
            raise simulation_error(self.path, sim, field, what) from err

    def _read_file_attrs(self, h5: h5py.File) -> dict[str, Any]:
        attrs = decode_attrs(h5.attrs)
        if attrs.get("format") != FORMAT:
            got = attrs.get("format", "<missing>")
            raise simulation_error(
                self.path, None, "format", f"not a thrombojax dataset (format attribute {got!r})"
            )
        version = attrs.get("version")
        if not isinstance(version, int) or version > VERSION:
            raise simulation_error(
                self.path, None, "version", f"unsupported version {version!r} (max {VERSION})"
            )
        config = attrs.get("generator_config", "null")
        try:
            attrs["generator_config"] = json.loads(config) if isinstance(config, str) else config
        except json.JSONDecodeError as err:
            raise simulation_error(self.path, None, "generator_config", f"bad JSON: {err}") from err
        return attrs

    def _check_structure(self, group: h5py.Group, name: str) -> tuple[int, int]:
        """Check fields, ranks and dtypes of one simulation from metadata; return (T, N)."""
        sim = group[name]

        def fail(key: str, problem: str) -> DatasetError:
            return simulation_error(self.path, name, key, problem)

        def field(key: str, required: bool = True) -> h5py.Dataset | None:
            obj = sim.get(key) if isinstance(sim, h5py.Group) else None
            if obj is None and required:
                raise fail(key, "missing")
            if obj is not None and not isinstance(obj, h5py.Dataset):
                raise fail(key, "is not an array")
            return obj if obj is None else check_stored_size(obj, key, fail)  # no 6 GB reads

        pos = field("positions")
        if pos.dtype != np.float32:
            raise fail("positions", f"wrong dtype {pos.dtype}, expected float32")
        n_frames, n_nodes = check_positions_shape(pos.shape, fail)
        nt = field("node_type")
        if nt.dtype.kind not in "iu" or nt.ndim != 1:
            raise fail("node_type", f"wrong dtype/shape {nt.dtype} {nt.shape}, expected int8 [N]")
        if nt.shape[0] != n_nodes:
            raise fail("node_type", f"length {nt.shape[0]} != {n_nodes} nodes in 'positions'")
        for key, width in _CELLS.items():
            c = field(key, required=False)
            if c is not None and (c.dtype.kind not in "iu" or c.ndim != 2 or c.shape[1] != width):
                raise fail(key, f"wrong dtype/shape {c.dtype} {c.shape}, expected int32 "
                           f"[cells, {width}]")
        return int(n_frames), int(n_nodes)

    def _name(self, name: str) -> str:
        if name not in self._shapes:
            raise KeyError(f"{self.path}: no simulation {name!r} (have {', '.join(self.names)})")
        return name

    def __len__(self) -> int:
        return len(self.names)

    def __iter__(self) -> Iterator[str]:
        return iter(self.names)

    def __contains__(self, name: object) -> bool:
        return name in self._shapes

    def __getitem__(self, name: str) -> Simulation:
        """Read one whole simulation and validate it (values, not only structure)."""
        name = self._name(name)
        fields: dict[str, Any] = {}
        for field in ("positions", "node_type", *_CELLS, "attrs"):
            with self._open(name, field) as h5:
                group = h5["simulations"][name]
                if field == "attrs":
                    fields[field] = decode_attrs(group.attrs)
                else:
                    fields[field] = group[field][()] if field in group else None
        sim = Simulation(name=name, **fields)
        validate_simulation(sim, path=self.path)
        return sim

    def n_frames(self, name: str) -> int:
        return self._shapes[self._name(name)][0]

    def n_nodes(self, name: str) -> int:
        return self._shapes[self._name(name)][1]

    def sim_attrs(self, name: str) -> dict[str, Any]:
        """Attributes of one simulation (dt, wall times, ...) without reading its arrays."""
        name = self._name(name)
        with self._open(name, "attrs") as h5:
            return decode_attrs(h5["simulations"][name].attrs)

    def node_type(self, name: str) -> np.ndarray:
        """``[N]`` int8 node types of one simulation (values checked: known, >= 1 clot)."""
        name = self._name(name)
        with self._open(name, "node_type") as h5:
            node_type = h5["simulations"][name]["node_type"][()]
        unknown = ~np.isin(node_type, KNOWN_NODE_TYPES)
        if unknown.any():
            raise simulation_error(self.path, name, "node_type", f"unknown node-type value "
                                   f"{int(node_type[np.argmax(unknown)])}")
        if not (node_type == NodeType.CLOT).any():
            raise simulation_error(self.path, name, "node_type", "no clot nodes")
        return node_type.astype(np.int8)

    def positions(self, name: str, frames: Any = None) -> np.ndarray:
        """Read some frames of one simulation (partial read).

        Args:
            name: simulation name.
            frames: None (all), an int, a slice, or an integer / bool array of frame indices.
        Returns:
            ``[n_selected, N, 3]`` float32 (``[N, 3]`` for an int).
        Raises:
            IndexError: a frame index is out of range.
            DatasetError: the frames read hold non-finite values.
        """
        name = self._name(name)
        n_frames = self.n_frames(name)
        try:
            idx = np.arange(n_frames)[slice(None) if frames is None else frames]
        except IndexError as err:
            raise IndexError(f"{self.path}: simulation '{name}': field 'positions': "
                             f"frames {frames!r} out of range for {n_frames} frames") from err
        flat = np.atleast_1d(idx)
        with self._open(name, "positions") as h5:
            data = h5["simulations"][name]["positions"]
            if flat.size and np.array_equal(flat, np.arange(flat[0], flat[0] + flat.size)):
                out = data[int(flat[0]) : int(flat[0]) + flat.size]
            else:
                uniq, inverse = np.unique(flat, return_inverse=True)
                out = data[uniq][inverse] if uniq.size else data[:0]
        if not np.isfinite(out).all():
            raise simulation_error(self.path, name, "positions", "non-finite values in frames read")
        return out[0] if np.ndim(idx) == 0 else out

    def validate(self, *, progress: bool = False) -> None:
        """Read and validate every simulation (one at a time)."""
        for name in tqdm(self.names, desc="validating", unit="sim", disable=not progress):
            self[name]

    def __repr__(self) -> str:
        return f"Dataset({str(self.path)!r}, {len(self)} simulations)"


def open_dataset(path: str | os.PathLike) -> Dataset:
    """Open a dataset file lazily (see :class:`Dataset`).

    Raises:
        FileNotFoundError: no such file.
        DatasetError: the file is not a readable thrombojax dataset (naming file, simulation,
            field).
    """
    return Dataset(path)
