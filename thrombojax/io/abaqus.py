"""Import Abaqus simulations: a flat ``.inp`` mesh and the per-frame coordinates from the ``.odb``.

The mesh comes from a flat ``.inp`` (one ``*Node`` block, written without parts/assembly, as
meshio reads it); the per-frame coordinates in one of the forms of :mod:`thrombojax.io.frames`.

Elements: clot elements are tetrahedra (``C3D4``, ``C3D10``, ...). Wall elements may be any
triangle or quadrilateral of the shell, surface, membrane or rigid families (``S3``, ``S3R``,
``STRI3``, ``M3D3``, ``SFM3D3``, ``R3D3``, ``S4``, ``S4R``, ``M3D4``, ``M3D4R``, ``SFM3D4``,
``SFM3D4R``, ``R3D4`` and their 6/8/9-node versions); quadrilaterals are stored as two triangles
and second-order elements by their corner nodes.

Nodes that belong to no element (e.g. the reference node of a rigid body) are not part of the
clot or the vessel and are dropped, with their labels recorded in the simulation attribute
``dropped_node_labels``; the frames may list all mesh nodes (the dropped rows are removed) or
only the kept ones. Messages name nodes by their Abaqus label.

Node types: ``clot_sets`` / ``vessel_sets`` name element or node sets (case-insensitive). With
``clot_sets`` given and no ``vessel_sets``, every other node is vessel. With neither, every set
whose name contains ``CLOT`` is clot and every set whose name contains ``VESSEL``, ``WALL`` or
``ARTERY`` is vessel (with clot sets but no vessel sets, all other nodes are vessel); without any
matching set the element types decide: tetrahedron nodes are clot, the other nodes vessel.

The simulation's name is the name of its frames source: a folder's name or a file's stem (the
same rule as :func:`thrombojax.io.meshio_import.read_mesh_series`).
"""

from __future__ import annotations

import os
import re
import tempfile
from collections.abc import Sequence
from pathlib import Path

import meshio
import numpy as np

from thrombojax.errors import ConfigError, DatasetError
from thrombojax.io.frames import read_frames, source_name
from thrombojax.io.hdf5 import write_dataset
from thrombojax.io.outputs import input_files
from thrombojax.io.schema import Simulation, simulation_error, validate_simulation
from thrombojax.study import UNKNOWN_KIND
from thrombojax.types import NodeType

__all__ = [
    "DEFAULT_CLOT_KEYWORDS", "DEFAULT_VESSEL_KEYWORDS", "WALL_ELEMENT_ALIASES", "read_abaqus",
    "import_abaqus",
]

DEFAULT_CLOT_KEYWORDS = ("CLOT",)
DEFAULT_VESSEL_KEYWORDS = ("VESSEL", "WALL", "ARTERY")
WALL_ELEMENT_ALIASES = {
    "M3D3": "S3", "SFM3D3": "S3", "M3D4": "S4", "M3D4R": "S4R", "SFM3D4": "S4",
    "SFM3D4R": "S4R", "R3D4": "S4", "M3D6": "STRI65", "SFM3D6": "STRI65", "M3D8": "S8R",
    "M3D8R": "S8R", "SFM3D8": "S8R", "SFM3D8R": "S8R", "M3D9": "S9R5", "M3D9R": "S9R5",
}
"""Abaqus wall element types meshio does not know -> a type with the same node layout."""

_TETRA = ("tetra", "tetra10")
_WALL_CORNERS = {"triangle": 3, "triangle6": 3, "quad": 4, "quad8": 4, "quad9": 4}
_TYPE = re.compile(r"(type\s*=\s*)([A-Za-z0-9]+)", re.IGNORECASE)


def _abaqus_labels(inp: Path, name: str) -> np.ndarray | None:
    """Node labels of the single ``*Node`` block, in file order (None with ``*Include``)."""
    labels, blocks, in_nodes, include = [], 0, False, False
    with open(inp, errors="replace") as f:
        for line in f:
            if line.startswith("**"):
                continue
            if line.startswith("*"):
                keyword = line[1:].partition(",")[0].strip().upper()
                in_nodes = keyword == "NODE"
                blocks += in_nodes
                include |= keyword == "INCLUDE"
            elif in_nodes and line.strip():
                try:
                    labels.append(int(line.split(",")[0]))
                except ValueError as err:
                    msg = f"bad *Node line {line.strip()!r}"
                    raise simulation_error(inp, name, "mesh", msg) from err
    if blocks > 1:
        raise simulation_error(inp, name, "mesh", f"{blocks} *Node blocks (parts/instances); "
                               "write the input file without parts and assembly")
    return None if include else np.asarray(labels, np.int64)


def _alias_line(line: str) -> str:
    if not line.lstrip().upper().startswith("*ELEMENT"):
        return line
    return _TYPE.sub(lambda m: m.group(1) + WALL_ELEMENT_ALIASES.get(m.group(2).upper(),
                                                                     m.group(2)), line)


def _read_inp(inp: Path, name: str) -> meshio.Mesh:
    """meshio's Abaqus reader, after renaming membrane/surface wall types (a temporary copy)."""
    text = inp.read_text(errors="replace")
    lines = text.splitlines(keepends=True)
    aliased = "".join(_alias_line(ln) for ln in lines)
    try:
        if aliased == text:
            return meshio.abaqus.read(str(inp))
        with tempfile.TemporaryDirectory() as tmp:
            copy = Path(tmp) / inp.name
            copy.write_text(aliased)
            return meshio.abaqus.read(str(copy))
    except Exception as err:  # meshio parsers raise many types: all mean a bad input file
        msg = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise simulation_error(inp, name, "mesh", f"cannot read: {msg}") from err


def _set_nodes(mesh: meshio.Mesh, key: str, path: Path, name: str) -> np.ndarray:
    """Node indices of a node set, or of the elements of an element set."""
    if key in mesh.point_sets:
        return np.asarray(mesh.point_sets[key], np.int64)
    try:
        parts = [mesh.cells[i].data[np.asarray(idx, np.int64)].ravel()
                 for i, idx in enumerate(mesh.cell_sets[key]) if len(idx)]
    except IndexError as err:
        raise simulation_error(path, name, "mesh", f"element set {key!r} does not match the "
                               "element blocks (define it with *Elset)") from err
    return np.unique(np.concatenate(parts)) if parts else np.zeros(0, np.int64)


def _pick_sets(mesh: meshio.Mesh, wanted, keywords, path, name, field) -> list[str]:
    available = {k.upper(): k for k in [*mesh.point_sets, *mesh.cell_sets]}
    if wanted:
        missing = [w for w in wanted if w.upper() not in available]
        if missing:
            raise simulation_error(path, name, field, f"no set {missing} in the .inp (have: "
                                   f"{sorted(available.values()) or 'none'})")
        return [available[w.upper()] for w in wanted]
    return [k for u, k in available.items() if any(word in u for word in keywords)]


def _cells(mesh: meshio.Mesh) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """(tetrahedra ``[C, 4]``, wall triangles ``[F, 3]``, every block's node indices)."""
    tets, tris, used = [], [], []
    for block in mesh.cells:
        data = np.asarray(block.data, np.int64)
        used.append(data.ravel())
        if block.type in _TETRA:
            tets.append(data[:, :4])
        elif _WALL_CORNERS.get(block.type) == 3:
            tris.append(data[:, :3])
        elif _WALL_CORNERS.get(block.type) == 4:
            tris += [data[:, [0, 1, 2]], data[:, [0, 2, 3]]]
    tets = np.concatenate(tets) if tets else np.zeros((0, 4), np.int64)
    tris = np.concatenate(tris) if tris else np.zeros((0, 3), np.int64)
    return tets, tris, used


def _node_types(mesh, clot_sets, vessel_sets, used, tets, inp, name, label) -> np.ndarray:
    """``[N]`` bool clot mask over all mesh nodes (non-clot element nodes are vessel)."""
    n_nodes = len(mesh.points)
    clot_keys = _pick_sets(mesh, clot_sets, DEFAULT_CLOT_KEYWORDS, inp, name, "clot_sets")
    vessel_keys = [] if clot_sets and not vessel_sets else _pick_sets(
        mesh, vessel_sets, DEFAULT_VESSEL_KEYWORDS, inp, name, "vessel_sets")
    if not clot_keys:
        if not tets.size:
            raise simulation_error(inp, name, "node_type", "no clot set and no tetrahedral "
                                   "elements to mark the clot")
        clot = np.zeros(n_nodes, bool)
        clot[tets.ravel()] = True
        return clot
    clot = np.zeros(n_nodes, bool)
    for key in clot_keys:
        clot[_set_nodes(mesh, key, inp, name)] = True
    if not vessel_keys:
        return clot
    vessel = np.zeros(n_nodes, bool)
    for key in vessel_keys:
        vessel[_set_nodes(mesh, key, inp, name)] = True
    both = clot & vessel
    if both.any():
        raise simulation_error(inp, name, "node_type", f"node {label(int(np.argmax(both)))} is "
                               f"in clot sets {clot_keys} and vessel sets {vessel_keys}")
    in_element = np.zeros(n_nodes, bool)
    in_element[np.concatenate(used)] = True
    neither = in_element & ~(clot | vessel)
    if neither.any():
        raise simulation_error(inp, name, "node_type", f"node {label(int(np.argmax(neither)))} "
                               f"is in no clot set {clot_keys} nor vessel set {vessel_keys}")
    return clot


def read_abaqus(
    inp: str | os.PathLike,
    frames: str | os.PathLike,
    *,
    name: str | None = None,
    clot_sets: Sequence[str] | None = None,
    vessel_sets: Sequence[str] | None = None,
    attrs: dict | None = None,
) -> Simulation:
    """Read one simulation from an Abaqus ``.inp`` mesh and its per-frame coordinates.

    Args:
        inp: flat Abaqus input file (one ``*Node`` block).
        frames: per-frame coordinates (:mod:`thrombojax.io.frames`), for all mesh nodes or only
            the nodes in elements.
        name: simulation name (default: the frames' folder name or file stem).
        clot_sets / vessel_sets: element or node set names (module docstring).
        attrs: simulation attributes (dt, reference_wall_time_s, ...).
    Returns:
        The validated :class:`Simulation` (nodes in no element dropped).
    """
    inp, frames = Path(inp), Path(frames)
    if not inp.is_file():
        raise FileNotFoundError(f"{inp}: no such .inp file")
    name = name or source_name(frames)
    labels = _abaqus_labels(inp, name)
    mesh = _read_inp(inp, name)
    n_nodes = len(mesh.points)
    if labels is not None and len(labels) != n_nodes:
        labels = None

    def label(i: int) -> str:
        return f"label {labels[i]}" if labels is not None else f"#{i + 1} (in file order)"

    tets, tris, used = _cells(mesh)
    clot = _node_types(mesh, clot_sets, vessel_sets, used, tets, inp, name, label)
    keep = np.zeros(n_nodes, bool)
    if used:
        keep[np.concatenate(used)] = True
    new_index = np.cumsum(keep) - 1
    node_type = np.where(clot[keep], NodeType.CLOT, NodeType.VESSEL).astype(np.int8)
    clot_cells = new_index[tets[clot[tets].all(axis=1)]].astype(np.int32)
    wall_cells = new_index[tris[(~clot[tris]).all(axis=1)]].astype(np.int32)
    positions = read_frames(frames, n_nodes=n_nodes, labels=labels, name=name, keep=keep)
    extra = {"source_inp": str(inp), "source_frames": str(frames)}
    if not keep.all():
        dropped = np.flatnonzero(~keep)
        extra["dropped_node_labels"] = ", ".join(
            str(labels[i]) if labels is not None else f"#{i + 1}" for i in dropped)
    sim = Simulation(name, positions, node_type, clot_cells if clot_cells.size else None,
                     wall_cells if wall_cells.size else None, {**(attrs or {}), **extra})
    try:
        validate_simulation(sim, path=frames)
    except DatasetError as err:
        kept = np.flatnonzero(keep)
        raise DatasetError(re.sub(r"node (\d+)", lambda m: f"node {label(int(kept[int(m[1])]))}"
                                  if int(m[1]) < kept.size else m[0], str(err))) from err
    return sim


def _names(names: Sequence[str] | None, n: int) -> list[str | None]:
    if names is None or len(names) == 0:
        return [None] * n
    if len(names) != n:
        raise ConfigError(f"{len(names)} names given for {n} simulations")
    return list(names)


def import_abaqus(
    inps: Sequence[str | os.PathLike], frames: Sequence[str | os.PathLike],
    out: str | os.PathLike, *, names: Sequence[str] | None = None,
    dataset_name: str | None = None, clot_sets: Sequence[str] | None = None,
    vessel_sets: Sequence[str] | None = None, dt: float | None = None,
    reference_wall_time_s: float | None = None, units: str = "vessel radius",
    overwrite: bool = False, progress: bool = True, kind: str = UNKNOWN_KIND,
    skip_frames: int = 0,
) -> Path:
    """Import Abaqus simulations (one ``.inp`` for all, or one per frames source) into one file.

    Args:
        inps: one ``.inp`` shared by all simulations, or one per frames source.
        frames: per simulation, its coordinates (a ``.npy`` or a folder; :mod:`.frames`).
        out: dataset file to write (atomically).
        names: one simulation name per frames source (default: their names, module docstring).
        clot_sets, vessel_sets: set names (default: by keyword; :func:`read_abaqus`).
        dt, reference_wall_time_s: stored as attributes of every simulation.
        dataset_name: file attribute ``name`` (default: ``out``'s stem).
        units: length unit of the coordinates (file attribute ``units``, shown in reports).
        overwrite, progress: replace an existing ``out``; progress bar over simulations.
        kind, skip_frames: which of the study's datasets this is like and the leading frames
            rollouts skip (file attributes, :mod:`thrombojax.study`; default ``unknown``, 0).
    Returns:
        The written path.
    """
    if len(inps) not in (1, len(frames)):
        raise ConfigError(f"{len(inps)} .inp files for {len(frames)} frame sources: give one "
                           ".inp for all or one per frame source")
    inps = list(inps) * len(frames) if len(inps) == 1 else list(inps)
    attrs = {k: v for k, v in (("dt", dt), ("reference_wall_time_s", reference_wall_time_s))
             if v is not None}
    sims = (read_abaqus(i, f, name=n, clot_sets=clot_sets, vessel_sets=vessel_sets, attrs=attrs)
            for i, f, n in zip(inps, frames, _names(names, len(frames)), strict=True))
    return write_dataset(out, sims, name=dataset_name or Path(out).stem, source="abaqus import",
                         units=units, overwrite=overwrite, progress=progress,
                         kind=kind, skip_frames=skip_frames,
                         inputs=input_files([*inps, *frames]))
