"""Import solver output into the dataset schema: mesh-file series and Abaqus ``.inp`` + frames.

**Mesh series** (:func:`read_mesh_series`): one VTU / VTK / XDMF file per frame, all with the same
points in the same order, read with meshio, frames in natural file-name order. The node type comes
from a point-data array (``node_type_array``; by default ``"node_type"`` is used when present;
values 0 = vessel, 1 = clot, integer or integral floats) or else from the cell blocks of the first
frame: nodes of ``tetra`` cells are clot, nodes of ``triangle`` cells (and no tetra) are vessel
wall.
Tetrahedra become ``clot_cells``; triangles whose nodes are all vessel become ``wall_cells``
(triangles entirely on the clot are its surface and are not stored; a triangle mixing clot and
vessel nodes, or a node in no tetra/triangle, is an error).

**Abaqus** (:func:`read_abaqus`): the mesh from a flat ``.inp`` (one ``*Node`` block, i.e. written
without parts/assembly, as meshio reads it) and the per-frame node coordinates exported from the
``.odb``, in one of these forms (``frames``):

- one ``.npy`` file holding a float array ``[T, N, 3]``;
- a folder of per-frame files ``frame_0000.npy``, ``frame_0001.npy``, ... (each ``[N, 3]``) or
  ``frame_0000.csv``, ... (natural file-name order; any names work, one suffix per folder).
  A CSV has one row per node, comma- or whitespace-separated, an optional header line, and
  either 3 columns ``x, y, z`` in the ``.inp`` node order or 4 columns ``label, x, y, z``
  (Abaqus node labels, any order).

Node types of an Abaqus mesh come from its element or node sets: ``clot_sets`` / ``vessel_sets``
name them (case-insensitive); by default every set whose name contains ``CLOT`` is clot and every
set whose name contains ``VESSEL``, ``WALL`` or ``ARTERY`` is vessel (with clot sets but no vessel
sets, all other nodes are vessel); without any matching set the element types decide as above.

:func:`import_mesh_series` and :func:`import_abaqus` stream many simulations into one file.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import meshio
import numpy as np
from tqdm import tqdm

from thrombojax.errors import ConfigError, DatasetError
from thrombojax.io.frames import list_frame_files, read_frames
from thrombojax.io.hdf5 import write_dataset
from thrombojax.io.outputs import input_files
from thrombojax.io.schema import Simulation, simulation_error, validate_simulation
from thrombojax.types import NodeType

__all__ = [
    "MESH_SUFFIXES", "DEFAULT_NODE_TYPE_ARRAY", "DEFAULT_CLOT_KEYWORDS", "DEFAULT_VESSEL_KEYWORDS",
    "list_frame_files", "node_type_from_cells", "read_mesh_series", "read_frames", "read_abaqus",
    "import_mesh_series", "import_abaqus",
]

MESH_SUFFIXES = (".vtu", ".vtk", ".xdmf", ".xmf")
DEFAULT_NODE_TYPE_ARRAY = "node_type"
DEFAULT_CLOT_KEYWORDS = ("CLOT",)
DEFAULT_VESSEL_KEYWORDS = ("VESSEL", "WALL", "ARTERY")
_TETRA = ("tetra", "tetra4")
_READERS = {
    "vtu": meshio.vtu.read,
    "vtk": meshio.vtk.read,
    "xdmf": meshio.xdmf.read,
    "xmf": meshio.xdmf.read,
    "abaqus": meshio.abaqus.read,
}


def node_type_from_cells(
    n_nodes: int,
    cells: Sequence[tuple[str, np.ndarray]],
    *,
    path: Any = "<memory>",
    name: str = "?",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node types from cell blocks: tetra nodes are clot, other triangle nodes vessel wall.

    Args:
        n_nodes: N.
        cells: (meshio cell type, ``[n, k]`` int node indices) blocks.
    Returns:
        (node_type ``[N]`` int8, clot_cells ``[C, 4]`` int32, wall_cells ``[F, 3]`` int32).
    """
    tets = [np.asarray(d) for t, d in cells if t in _TETRA]
    tris = [np.asarray(d) for t, d in cells if t == "triangle"]
    tets = np.concatenate(tets).astype(np.int32) if tets else np.zeros((0, 4), np.int32)
    tris = np.concatenate(tris).astype(np.int32) if tris else np.zeros((0, 3), np.int32)
    if not tets.size:
        raise simulation_error(path, name, "node_type", "no point-data node type and no tetra "
                               "cells to mark the clot")
    for field, arr in (("clot_cells", tets), ("wall_cells", tris)):
        if arr.size and (arr.min() < 0 or arr.max() >= n_nodes):
            raise simulation_error(path, name, field, f"node index out of range [0, {n_nodes})")
    clot = np.zeros(n_nodes, bool)
    clot[tets.ravel()] = True
    wall = np.zeros(n_nodes, bool)
    wall[tris.ravel()] = True
    orphan = ~(clot | wall)
    if orphan.any():
        raise simulation_error(path, name, "node_type", f"{int(orphan.sum())} nodes (first: "
                               f"{int(np.argmax(orphan))}) are in no tetra or triangle cell; give "
                               "the node type as a point-data array")
    on_clot = clot[tris].sum(axis=1)
    mixed = (on_clot > 0) & (on_clot < 3)
    if mixed.any():
        raise simulation_error(path, name, "wall_cells", f"triangle {int(np.argmax(mixed))} "
                               "joins clot and vessel nodes")
    node_type = np.where(clot, NodeType.CLOT, NodeType.VESSEL).astype(np.int8)
    return node_type, tets, tris[on_clot == 0]


def _point_node_type(mesh: meshio.Mesh, array: str, path: Path, name: str) -> np.ndarray:
    values = np.asarray(mesh.point_data[array])
    if values.ndim == 2 and values.shape[1] == 1:
        values = values[:, 0]
    if values.ndim != 1 or values.dtype.kind not in "iuf":
        raise simulation_error(path, name, "node_type", f"point-data array '{array}' has "
                               f"dtype/shape {values.dtype} {values.shape}, expected integers [N]")
    if values.dtype.kind == "f":
        if not (np.isfinite(values).all() and np.array_equal(values, np.round(values))):
            raise simulation_error(path, name, "node_type", f"point-data array '{array}' "
                                   "holds non-integer values")
    if values.min() < np.iinfo(np.int8).min or values.max() > np.iinfo(np.int8).max:
        raise simulation_error(path, name, "node_type", f"unknown node-type value "
                               f"{values.max() if values.max() > 127 else values.min()}")
    return values.astype(np.int8)


def _read_mesh(path: Path, name: str, file_format: str | None = None) -> meshio.Mesh:
    """Read with the format's own meshio reader (``meshio.read`` prints and exits on failure)."""
    kind = file_format or path.suffix.lower().lstrip(".")
    reader = _READERS.get(kind)
    if reader is None:
        raise simulation_error(path, name, "mesh", f"unsupported format '{kind}'")
    try:
        return reader(str(path))
    except Exception as err:  # meshio parsers raise many types: all mean a bad input file
        msg = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise simulation_error(path, name, "mesh", f"cannot read: {msg}") from err


def _frame_points(points: np.ndarray, n_nodes: int, path: Path, name: str) -> np.ndarray:
    points = np.asarray(points)
    if points.ndim != 2 or points.shape[1] != 3:
        raise simulation_error(path, name, "positions", f"points of shape {points.shape}, "
                               "expected [N, 3]")
    if points.shape[0] != n_nodes:
        raise simulation_error(path, name, "positions", f"{points.shape[0]} nodes, but the "
                               f"first frame has {n_nodes}")
    return points.astype(np.float32)


def read_mesh_series(
    source: str | os.PathLike | Sequence,
    *,
    name: str | None = None,
    node_type_array: str | None = None,
    attrs: dict | None = None,
    progress: bool = False,
) -> Simulation:
    """Read one simulation from a series of mesh files, one per frame (module docstring).

    Args:
        source: a folder of frame files, a glob pattern, or a list of files.
        name: simulation name (default: the folder's name).
        node_type_array: point-data array holding the node type; required when given, else
            ``"node_type"`` if present, else the cell blocks decide.
        attrs: simulation attributes (dt, reference_wall_time_s, ...).
    Returns:
        The validated :class:`Simulation`, positions ``[T, N, 3]`` float32.
    """
    files = list_frame_files(source, MESH_SUFFIXES)
    name = name or _default_name(source, files)
    first = _read_mesh(files[0], name)
    n_nodes = len(first.points)
    array = node_type_array or DEFAULT_NODE_TYPE_ARRAY
    if array in first.point_data:
        node_type = _point_node_type(first, array, files[0], name)
        tets = [c.data for c in first.cells if c.type in _TETRA]
        tris = [c.data for c in first.cells if c.type == "triangle"]
        clot_cells = np.concatenate(tets).astype(np.int32) if tets else None
        wall_cells = np.concatenate(tris).astype(np.int32) if tris else None
    elif node_type_array is not None:
        raise simulation_error(files[0], name, "node_type", f"no point-data array "
                               f"'{node_type_array}' (have: {sorted(first.point_data) or 'none'})")
    else:
        blocks = [(c.type, c.data) for c in first.cells]
        node_type, clot_cells, wall_cells = node_type_from_cells(
            n_nodes, blocks, path=files[0], name=name)
        wall_cells = wall_cells if wall_cells.size else None
    positions = np.empty((len(files), n_nodes, 3), np.float32)
    positions[0] = _frame_points(first.points, n_nodes, files[0], name)
    for t, path in enumerate(tqdm(files[1:], desc=name, disable=not progress), start=1):
        positions[t] = _frame_points(_read_mesh(path, name).points, n_nodes, path, name)
    origin = f"{files[0]} ... ({len(files)} files)" if isinstance(source, list | tuple) else source
    sim = Simulation(name, positions, node_type, clot_cells, wall_cells,
                     {**(attrs or {}), "source_files": str(origin)})
    validate_simulation(sim, path=source)
    return sim


def _default_name(source: Any, files: list[Path]) -> str:
    if not isinstance(source, list | tuple) and Path(source).is_dir():
        return Path(source).resolve().name
    return files[0].parent.resolve().name or "simulation"


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
        frames: per-frame coordinates (module docstring).
        name: simulation name (default: the frames' file or folder name).
        clot_sets / vessel_sets: element or node set names (default: by keyword).
        attrs: simulation attributes (dt, reference_wall_time_s, ...).
    Returns:
        The validated :class:`Simulation`.
    """
    inp, frames = Path(inp), Path(frames)
    if not inp.is_file():
        raise FileNotFoundError(f"{inp}: no such .inp file")
    name = name or frames.stem
    labels = _abaqus_labels(inp, name)
    mesh = _read_mesh(inp, name, file_format="abaqus")
    n_nodes = len(mesh.points)
    clot_keys = _pick_sets(mesh, clot_sets, DEFAULT_CLOT_KEYWORDS, inp, name, "clot_sets")
    vessel_keys = _pick_sets(mesh, vessel_sets, DEFAULT_VESSEL_KEYWORDS, inp, name, "vessel_sets")
    blocks = [(c.type, c.data) for c in mesh.cells]
    if clot_keys:
        clot = np.zeros(n_nodes, bool)
        for key in clot_keys:
            clot[_set_nodes(mesh, key, inp, name)] = True
        vessel = np.zeros(n_nodes, bool) if vessel_keys else ~clot
        for key in vessel_keys:
            vessel[_set_nodes(mesh, key, inp, name)] = True
        if (clot & vessel).any():
            raise simulation_error(inp, name, "node_type", f"node {int(np.argmax(clot & vessel))} "
                                   f"is in clot sets {clot_keys} and vessel sets {vessel_keys}")
        if not (clot | vessel).all():
            raise simulation_error(inp, name, "node_type", f"node {int(np.argmin(clot | vessel))} "
                                   f"is in no clot set {clot_keys} nor vessel set {vessel_keys}")
        node_type = np.where(clot, NodeType.CLOT, NodeType.VESSEL).astype(np.int8)
        tets = [d for t, d in blocks if t in _TETRA]
        tris = [d for t, d in blocks if t == "triangle"]
        tets = np.concatenate(tets) if tets else np.zeros((0, 4), np.int64)
        tris = np.concatenate(tris) if tris else np.zeros((0, 3), np.int64)
        clot_cells = tets[clot[tets].all(axis=1)].astype(np.int32)
        wall_cells = tris[vessel[tris].all(axis=1)].astype(np.int32)
    else:
        node_type, clot_cells, wall_cells = node_type_from_cells(n_nodes, blocks, path=inp,
                                                                 name=name)
    positions = read_frames(frames, n_nodes=n_nodes, labels=labels, name=name)
    sim = Simulation(
        name, positions, node_type,
        clot_cells if clot_cells.size else None, wall_cells if wall_cells.size else None,
        {**(attrs or {}), "source_inp": str(inp), "source_frames": str(frames)},
    )
    validate_simulation(sim, path=frames)
    return sim


def _names(names: Sequence[str] | None, n: int) -> list[str | None]:
    if names is None or len(names) == 0:
        return [None] * n
    if len(names) != n:
        raise ConfigError(f"{len(names)} names given for {n} simulations")
    return list(names)


def _sim_attrs(dt: float | None, reference_wall_time_s: float | None) -> dict:
    out = {"dt": dt, "reference_wall_time_s": reference_wall_time_s}
    return {k: v for k, v in out.items() if v is not None}


def import_mesh_series(
    sources: Sequence[str | os.PathLike], out: str | os.PathLike, *,
    names: Sequence[str] | None = None, dataset_name: str | None = None,
    node_type_array: str | None = None, dt: float | None = None,
    reference_wall_time_s: float | None = None, units: str = "vessel radius",
    overwrite: bool = False, progress: bool = True,
) -> Path:
    """Import mesh-file series (one folder or glob per simulation) into one dataset file.

    Args:
        sources: per simulation, a folder of frame files, a glob pattern or a list of files.
        out: dataset file to write (atomically).
        names: one simulation name per source (default: folder names).
        dataset_name: file attribute ``name`` (default: ``out``'s stem).
        node_type_array, dt, reference_wall_time_s: see :func:`read_mesh_series`; the times
            are stored as attributes of every simulation.
        units: unit of the coordinates.
        overwrite: replace an existing ``out``.
        progress: progress bar over simulations.
    Returns:
        The written path. Simulations are read and written one at a time.
    """
    for src in sources:
        if not isinstance(src, list | tuple) and Path(src).is_file():
            raise DatasetError(f"{src}: is one file; give the folder holding a simulation's frames "
                               "or a quoted glob such as 'run1/*.vtu' (one source per simulation)")
    attrs = _sim_attrs(dt, reference_wall_time_s)
    sims = (read_mesh_series(src, name=n, node_type_array=node_type_array, attrs=attrs)
            for src, n in zip(sources, _names(names, len(sources)), strict=True))
    return write_dataset(out, sims, name=dataset_name or Path(out).stem, source="meshio import",
                         units=units, overwrite=overwrite, progress=progress,
                         inputs=input_files(sources))


def import_abaqus(
    inps: Sequence[str | os.PathLike], frames: Sequence[str | os.PathLike],
    out: str | os.PathLike, *, names: Sequence[str] | None = None,
    dataset_name: str | None = None, clot_sets: Sequence[str] | None = None,
    vessel_sets: Sequence[str] | None = None, dt: float | None = None,
    reference_wall_time_s: float | None = None, units: str = "vessel radius",
    overwrite: bool = False, progress: bool = True,
) -> Path:
    """Import Abaqus simulations (one ``.inp`` for all, or one per frames source) into one file.

    Args:
        inps: one ``.inp`` shared by all simulations, or one per frames source.
        frames: per simulation, its coordinates (a ``.npy`` or a folder; :mod:`.frames`).
        out: dataset file to write (atomically).
        names: one simulation name per frames source (default: their stems).
        clot_sets, vessel_sets: set names (default: by keyword; :func:`read_abaqus`).
        dt, reference_wall_time_s: stored as attributes of every simulation.
        dataset_name, units, overwrite, progress: as :func:`import_mesh_series`.
    Returns:
        The written path.
    """
    if len(inps) not in (1, len(frames)):
        raise ConfigError(f"{len(inps)} .inp files for {len(frames)} frame sources: give one "
                           ".inp for all or one per frame source")
    inps = list(inps) * len(frames) if len(inps) == 1 else list(inps)
    attrs = _sim_attrs(dt, reference_wall_time_s)
    sims = (read_abaqus(i, f, name=n, clot_sets=clot_sets, vessel_sets=vessel_sets, attrs=attrs)
            for i, f, n in zip(inps, frames, _names(names, len(frames)), strict=True))
    return write_dataset(out, sims, name=dataset_name or Path(out).stem, source="abaqus import",
                         units=units, overwrite=overwrite, progress=progress,
                         inputs=input_files([*inps, *frames]))
