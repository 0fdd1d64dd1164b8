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

**Single-file series**: one ``.pvd`` collection or one XDMF file with a temporal collection
(``thrombojax export`` writes both) is one simulation; its times give ``dt``
(:mod:`thrombojax.io.series_file`).

**Abaqus**: :func:`read_abaqus` and :func:`import_abaqus` live in :mod:`thrombojax.io.abaqus`
(re-exported here).

Names: a simulation is named after its source, a folder's name or a series file's stem (the
same rule for Abaqus frames; :func:`thrombojax.io.frames.source_name`). ``units`` (the length
unit of the coordinates) is stored in the dataset file and shown by every report.

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
from thrombojax.io.abaqus import (
    DEFAULT_CLOT_KEYWORDS,
    DEFAULT_VESSEL_KEYWORDS,
    import_abaqus,
    read_abaqus,
)
from thrombojax.io.frames import list_frame_files, read_frames, source_name
from thrombojax.io.hdf5 import write_dataset
from thrombojax.io.outputs import input_files
from thrombojax.io.schema import Simulation, simulation_error, validate_simulation
from thrombojax.io.series_file import is_series_file, read_pvd, read_xdmf_series, series_dt
from thrombojax.study import UNKNOWN_KIND
from thrombojax.types import NodeType

__all__ = [
    "MESH_SUFFIXES", "DEFAULT_NODE_TYPE_ARRAY", "DEFAULT_CLOT_KEYWORDS", "DEFAULT_VESSEL_KEYWORDS",
    "list_frame_files", "node_type_from_cells", "read_mesh_series", "read_frames", "read_abaqus",
    "import_mesh_series", "import_abaqus",
]

MESH_SUFFIXES = (".vtu", ".vtk", ".xdmf", ".xmf")
DEFAULT_NODE_TYPE_ARRAY = "node_type"
_TETRA = ("tetra", "tetra4")
_READERS = {
    "vtu": meshio.vtu.read,
    "vtk": meshio.vtk.read,
    "xdmf": meshio.xdmf.read,
    "xmf": meshio.xdmf.read,
}


def node_type_from_cells(
    n_nodes: int,
    cells: Sequence[tuple[str, np.ndarray]],
    *,
    path: Any = "<memory>",
    name: str = "?",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node types from cell blocks: tetra nodes are clot, other triangle (or quad) nodes vessel.

    Args:
        n_nodes: N.
        cells: (meshio cell type, ``[n, k]`` int node indices) blocks.
    Returns:
        (node_type ``[N]`` int8, clot_cells ``[C, 4]`` int32, wall_cells ``[F, 3]`` int32).
    """
    tets = [np.asarray(d) for t, d in cells if t in _TETRA]
    tris = [np.asarray(d) for t, d in cells if t == "triangle"]
    quads = [np.asarray(d) for t, d in cells if t == "quad"]  # a quad wall: two triangles each
    tris += [q[:, idx] for q in quads for idx in ([0, 1, 2], [0, 2, 3])]
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
    """Read one simulation from a series of mesh files or one series file (module docstring).

    Args:
        source: a folder of frame files, a glob pattern, a list of files, or one ``.pvd`` /
            XDMF temporal-collection file (:mod:`thrombojax.io.series_file`).
        name: simulation name (default: the folder's name, or the series file's stem).
        node_type_array: point-data array holding the node type; required when given, else
            ``"node_type"`` if present, else the cell blocks decide.
        attrs: simulation attributes (dt, reference_wall_time_s, ...). A series file's times
            give ``dt`` (checked against a given one).
    Returns:
        The validated :class:`Simulation`, positions ``[T, N, 3]`` float32.
    """
    attrs, positions = dict(attrs or {}), None
    name = name or source_name(source)
    if is_series_file(source) and Path(source).suffix.lower() == ".pvd":
        times, files = read_pvd(source, name)
        first = _read_mesh(files[0], name)
    elif is_series_file(source):
        first, positions, times = read_xdmf_series(source, name)
        files = [Path(source)]
    else:
        times, files = None, list_frame_files(source, MESH_SUFFIXES)
        first = _read_mesh(files[0], name)
    if times is not None:
        dt = series_dt(times, attrs.get("dt"), source, name)
        attrs |= {"dt": dt} if dt is not None else {}
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
    if positions is None:
        positions = np.empty((len(files), n_nodes, 3), np.float32)
        positions[0] = _frame_points(first.points, n_nodes, files[0], name)
        for t, path in enumerate(tqdm(files[1:], desc=name, disable=not progress), start=1):
            positions[t] = _frame_points(_read_mesh(path, name).points, n_nodes, path, name)
    origin = f"{files[0]} ... ({len(files)} files)" if isinstance(source, list | tuple) else source
    sim = Simulation(name, positions, node_type, clot_cells, wall_cells,
                     {**attrs, "source_files": str(origin)})
    validate_simulation(sim, path=source)
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
    overwrite: bool = False, progress: bool = True, kind: str = UNKNOWN_KIND,
    skip_frames: int = 0,
) -> Path:
    """Import mesh-file series (one folder or glob per simulation) into one dataset file.

    Args:
        sources: per simulation, a folder of frame files, a glob pattern, a list of files or
            one ``.pvd`` / XDMF time-series file.
        out: dataset file to write (atomically).
        names: one simulation name per source (default: folder names or series-file stems).
        dataset_name: file attribute ``name`` (default: ``out``'s stem).
        node_type_array, dt, reference_wall_time_s: see :func:`read_mesh_series`; the times
            are stored as attributes of every simulation.
        units: length unit of the coordinates (file attribute ``units``, shown in reports).
        overwrite: replace an existing ``out``.
        progress: progress bar over simulations.
        kind, skip_frames: which of the study's datasets this is like and the leading frames
            rollouts skip (file attributes, :mod:`thrombojax.study`; default ``unknown``, 0).
    Returns:
        The written path. Simulations are read and written one at a time.
    """
    for src in sources:
        if not isinstance(src, list | tuple) and Path(src).is_file() and not is_series_file(src):
            raise DatasetError(f"{src}: is one frame file; give the folder holding a simulation's "
                               "frames, a quoted glob such as 'run1/*.vtu', or one .pvd / XDMF "
                               "time-series file (one source per simulation)")
    attrs = _sim_attrs(dt, reference_wall_time_s)
    sims = (read_mesh_series(src, name=n, node_type_array=node_type_array, attrs=attrs)
            for src, n in zip(sources, _names(names, len(sources)), strict=True))
    return write_dataset(out, sims, name=dataset_name or Path(out).stem, source="meshio import",
                         units=units, overwrite=overwrite, progress=progress,
                         kind=kind, skip_frames=skip_frames,
                         inputs=input_files(sources))
