"""The in-memory simulation record and its validation (the rules of the dataset schema).

A :class:`Simulation` is one trajectory: positions ``[T, N, 3]`` in physical units, one node type
per node, optional clot tetrahedra and wall triangles, and a flat dictionary of attributes.
:func:`validate_simulation` enforces the schema of ``docs/dataset.md``; the HDF5 writer and reader
(:mod:`thrombojax.io.hdf5`) and every importer call it, so a bad simulation never enters or
leaves a dataset file. Every error names the file, the simulation and the field:
``"<file>: simulation '<name>': field '<field>': <problem>"``.

Vessel rigidity tolerance: a vessel node may deviate from its frame-0 position by at most
``vessel_tol * L`` per coordinate, where ``L`` is the largest side of the simulation's bounding
box over all frames (``vessel_tol`` defaults to :data:`VESSEL_TOLERANCE` = 1e-6), plus the float32
resolution of the largest coordinate magnitude (so exactly copied float32 frames always pass).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

from thrombojax.errors import DatasetError
from thrombojax.types import NodeType

__all__ = [
    "Simulation",
    "validate_simulation",
    "check_positions_shape",
    "check_stored_size",
    "simulation_error",
    "encode_attrs",
    "decode_attrs",
    "to_json",
    "natural_key",
    "bounding_box",
    "VESSEL_TOLERANCE",
    "KNOWN_NODE_TYPES",
]

VESSEL_TOLERANCE: float = 1e-6
"""Relative tolerance (times the bounding-box size) within which vessel nodes count as fixed."""

KNOWN_NODE_TYPES: tuple[int, ...] = tuple(int(t) for t in NodeType)

_TIME_ATTRS = ("solver_wall_time_s", "reference_wall_time_s")
_JSON_KEY = "_json_attrs"


@dataclasses.dataclass(frozen=True, eq=False)  # arrays: compare fields explicitly
class Simulation:
    """One simulated trajectory, in physical units.

    Attributes:
        name: identifier, unique within a dataset (no ``/``).
        positions: ``[T, N, 3]`` float32 node positions of every stored frame.
        node_type: ``[N]`` int8 :class:`~thrombojax.types.NodeType` values.
        clot_cells: ``[C, 4]`` int32 clot tetrahedra (node indices) or None.
        wall_cells: ``[F, 3]`` int32 vessel-wall triangles (node indices) or None.
        attrs: ``dt``, ``solver_wall_time_s``, ``reference_wall_time_s``, ``rotation_deg``,
            ``seed``, geometry parameters... (str, bool, numbers, numeric arrays; lists,
            dicts and None are stored as JSON).
    """

    name: str
    positions: np.ndarray
    node_type: np.ndarray
    clot_cells: np.ndarray | None = None
    wall_cells: np.ndarray | None = None
    attrs: dict[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_nodes(self) -> int:
        return int(self.positions.shape[1])

    @property
    def clot_mask(self) -> np.ndarray:
        """``[N]`` bool, True for clot nodes."""
        return np.asarray(self.node_type) == NodeType.CLOT


def simulation_error(path: Any, sim: str | None, field: str | None, problem: str) -> DatasetError:
    """Build the one-line :class:`DatasetError` ``"<file>: simulation '<s>': field '<f>': ..."``."""
    parts = [str(path)]
    if sim is not None:
        parts.append(f"simulation '{sim}'")
    if field is not None:
        parts.append(f"field '{field}'")
    return DatasetError(": ".join([*parts, problem]))


def natural_key(name: str) -> list:
    """Sort key for natural order (``sim_2`` before ``sim_10``)."""
    # ASCII digits only: '²' is a digit to str.isdigit() but not to int()
    return [int(tok) if tok.isascii() and tok.isdigit() else tok.lower()
            for tok in re.split(r"([0-9]+)", name)]


def check_stored_size(array: Any, key: str, fail) -> Any:
    """Refuse an unfiltered HDF5 array that declares more bytes than the file stores.

    An 8 KB file may declare ``positions [500, 1000000, 3]`` (6 GB of fill values); reading it
    would take minutes and gigabytes. Checked from metadata before anything is read.
    ``fail(key, problem)`` builds the error. Returns ``array``.
    """
    declared = int(array.size) * int(array.dtype.itemsize)
    if not declared or array.id.get_create_plist().get_nfilters():
        return array  # compressed arrays may legitimately store fewer bytes
    stored = int(array.id.get_storage_size())
    if stored < declared:
        raise fail(key, f"declares shape {tuple(array.shape)} ({declared / 1e6:,.1f} MB) but the "
                        f"file stores {stored:,} bytes of it (truncated or forged file)")
    return array


def check_positions_shape(shape: tuple[int, ...], fail) -> tuple[int, int]:
    """Check that ``positions`` is a non-empty ``[frames, nodes, 3]`` array; return (T, N).

    Shared by validation in memory and the reader's metadata check (before any data is read).

    Args:
        shape: the array's shape. fail: ``fail(field, problem) -> DatasetError``.
    """
    if len(shape) != 3 or shape[2] != 3:
        raise fail("positions", f"wrong shape {tuple(shape)}, expected [frames, nodes, 3]")
    n_frames, n_nodes = int(shape[0]), int(shape[1])
    if n_frames == 0 or n_nodes == 0:
        raise fail("positions", f"empty simulation ({n_frames} frames, {n_nodes} nodes)")
    return n_frames, n_nodes


def validate_simulation(
    sim: Simulation, *, path: Any = "<memory>", vessel_tol: float = VESSEL_TOLERANCE
) -> None:
    """Check one simulation against the dataset schema; raise on the first problem.

    Checks: a valid name; positions a floating ``[T, N, 3]`` array with ``T, N >= 1`` and only
    finite values; node_type an integer ``[N]`` array of known values with at least one clot node;
    vessel nodes fixed within the tolerance (module docstring); cells integer ``[C, 4]`` /
    ``[F, 3]`` arrays of valid node indices; attributes a dict with string keys, and ``dt`` > 0,
    wall times >= 0 when present.

    Args:
        sim: the simulation.
        path: file the simulation comes from or goes to (for the message only).
        vessel_tol: relative tolerance of the vessel-rigidity check.
    Raises:
        DatasetError: naming ``path``, the simulation and the field.
    """
    name = sim.name
    if not isinstance(name, str) or not name or "/" in name or name in (".", ".."):
        raise simulation_error(path, repr(name), "name", "must be a non-empty string without '/'")

    def fail(field: str, problem: str) -> DatasetError:
        return simulation_error(path, name, field, problem)

    pos = sim.positions
    if not isinstance(pos, np.ndarray):
        raise fail("positions", f"expected a numpy array, got {type(pos).__name__}")
    if pos.dtype.kind != "f":
        raise fail("positions", f"wrong dtype {pos.dtype}, expected float32")
    _, n_nodes = check_positions_shape(pos.shape, fail)
    _check_finite(pos, fail)

    nt = sim.node_type
    if not isinstance(nt, np.ndarray):
        raise fail("node_type", f"expected a numpy array, got {type(nt).__name__}")
    if nt.dtype.kind not in "iu":
        raise fail("node_type", f"wrong dtype {nt.dtype}, expected int8")
    if nt.ndim != 1:
        raise fail("node_type", f"wrong rank {nt.ndim} (shape {nt.shape}), expected [nodes]")
    if nt.shape[0] != n_nodes:
        raise fail("node_type", f"length {nt.shape[0]} != {n_nodes} nodes in 'positions'")
    unknown = ~np.isin(nt, KNOWN_NODE_TYPES)
    if unknown.any():
        i = int(np.argmax(unknown))
        known = ", ".join(f"{int(t)}={t.name}" for t in NodeType)
        raise fail("node_type", f"unknown node-type value {int(nt[i])} at node {i} ({known})")
    if not (nt == NodeType.CLOT).any():
        raise fail("node_type", f"no clot nodes (no value {int(NodeType.CLOT)}=CLOT)")
    _check_vessel_fixed(pos, nt == NodeType.VESSEL, vessel_tol, fail)

    for field, arr, width in (("clot_cells", sim.clot_cells, 4), ("wall_cells", sim.wall_cells, 3)):
        if arr is not None:
            _check_cells(arr, width, n_nodes, lambda problem, f=field: fail(f, problem))
    _check_attrs(sim.attrs, fail)


def _check_finite(pos: np.ndarray, fail) -> None:
    """Raise naming the first non-finite value, frame by frame (no [T, N, 3] temporary)."""
    for t in range(pos.shape[0]):
        bad = ~np.isfinite(pos[t])
        if bad.any():
            node, axis = np.unravel_index(int(np.argmax(bad)), bad.shape)
            value = pos[t, node, axis]
            raise fail("positions", f"non-finite value {value} at frame {t}, node {node}")


def bounding_box(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounding box of ``[..., 3]`` positions: ``(lo [3], hi [3])`` float64.

    One strided reduction per axis (much faster than ``min(axis=(0, 1))`` on ``[T, N, 3]``).
    """
    flat = np.asarray(positions).reshape(-1, 3)
    lo = np.array([flat[:, k].min() for k in range(3)], np.float64)
    hi = np.array([flat[:, k].max() for k in range(3)], np.float64)
    return lo, hi


def _check_vessel_fixed(pos: np.ndarray, vessel: np.ndarray, rel_tol: float, fail) -> None:
    """Raise when a vessel node drifts from its frame-0 position by more than the tolerance."""
    if not vessel.any() or pos.shape[0] < 2:
        return
    lo, hi = bounding_box(pos)
    extent = float((hi - lo).max())
    magnitude = float(np.maximum(np.abs(lo), np.abs(hi)).max())
    tol = rel_tol * extent + 4.0 * float(np.finfo(np.float32).eps) * magnitude
    flat_mask = np.repeat(vessel, 3)  # frame by frame on flat [N * 3] rows: fast, no big copy
    ref = pos[0].reshape(-1)
    for t in range(1, pos.shape[0]):
        drift = np.abs(pos[t].reshape(-1) - ref)
        if float(drift[flat_mask].max()) > tol:
            per_node = np.where(vessel, drift.reshape(-1, 3).max(axis=1), 0.0)
            node = int(np.argmax(per_node))
            raise fail(
                "positions",
                f"vessel node {node} moves by {per_node[node]:.3g} at frame {t} (vessel nodes must "
                f"stay within {rel_tol:g} x bounding-box size {extent:.3g} + float32 round-off "
                f"= {tol:.3g})",
            )


def _check_cells(arr: Any, width: int, n_nodes: int, fail) -> None:
    if not isinstance(arr, np.ndarray):
        raise fail(f"expected a numpy array, got {type(arr).__name__}")
    if arr.dtype.kind not in "iu":
        raise fail(f"wrong dtype {arr.dtype}, expected int32")
    if arr.ndim != 2 or arr.shape[1] != width:
        raise fail(f"wrong shape {arr.shape}, expected [cells, {width}]")
    if arr.size and (arr.min() < 0 or arr.max() >= n_nodes):
        raise fail(f"node index out of range [0, {n_nodes}): min {arr.min()}, max {arr.max()}")


def _check_attrs(attrs: Any, fail) -> None:
    if not isinstance(attrs, dict):
        raise fail("attrs", f"expected a dict, got {type(attrs).__name__}")
    for key, value in attrs.items():
        if not isinstance(key, str) or not key or key.startswith("_"):
            raise fail("attrs", f"invalid attribute name {key!r} (non-empty, not starting '_')")
        if key == "dt" or key in _TIME_ATTRS:
            ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(
                value, bool
            )
            ok = ok and math.isfinite(float(value)) and float(value) >= 0
            if not ok or (key == "dt" and float(value) <= 0):
                bound = "> 0" if key == "dt" else ">= 0"
                raise fail(f"attrs/{key}", f"must be a finite number {bound}, got {value!r}")


def to_json(value: Any) -> str:
    """JSON text of ``value``; numpy scalars / arrays, dataclasses and paths are converted."""

    def default(obj: Any) -> Any:
        if isinstance(obj, np.generic | np.ndarray):
            return obj.tolist()
        if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            return dataclasses.asdict(obj)
        if isinstance(obj, os.PathLike):
            return os.fspath(obj)
        raise TypeError(f"{type(obj).__name__} is not JSON serialisable")

    return json.dumps(value, default=default)


def encode_attrs(target: Any, attrs: Mapping[str, Any]) -> None:
    """Store str/bool/number/numeric-array attributes natively in an HDF5 attribute manager,
    everything else as JSON (names listed in ``_json_attrs``)."""
    json_keys = []
    for key, value in attrs.items():
        if isinstance(value, str | bool | int | float | np.generic) or (
            isinstance(value, np.ndarray) and value.dtype.kind in "biuf"
        ):
            target[key] = value
        else:
            target[key] = to_json(value)
            json_keys.append(key)
    if json_keys:
        target[_JSON_KEY] = json.dumps(json_keys)


def decode_attrs(source: Any) -> dict[str, Any]:
    """Inverse of :func:`encode_attrs`: Python scalars, numpy arrays, decoded JSON."""
    json_keys = set(json.loads(source[_JSON_KEY])) if _JSON_KEY in source else set()
    out: dict[str, Any] = {}
    for key, value in source.items():
        if key == _JSON_KEY:
            continue
        if isinstance(value, bytes):
            value = value.decode()
        if key in json_keys:
            value = json.loads(value)
        elif isinstance(value, np.generic):
            value = value.item()
        out[key] = value
    return out
