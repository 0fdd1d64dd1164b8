"""Single-file time series: a ParaView ``.pvd`` collection or an XDMF temporal collection.

- ``.pvd`` (``VTKFile type="Collection"``): one ``DataSet`` per time step, each naming a mesh
  file (relative to the ``.pvd``'s folder); frames are ordered by ``timestep``. One part per time
  step (a multi-block series is refused).
- ``.xdmf`` / ``.xmf`` holding a ``Grid`` of ``CollectionType="Temporal"`` (XDMF 3, as written by
  ``thrombojax export``, meshio's ``TimeSeriesWriter`` and most solvers): the mesh and the point
  data of the first step come from ``meshio.xdmf.TimeSeriesReader``; the points of each step from
  its ``position`` point array when present (our exports), else from the step's own
  ``Geometry`` (XML or HDF5 data items), else the first step's points (a fixed mesh).

Both give the times of the frames; :func:`series_dt` turns them into the dataset's ``dt``.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from thrombojax.io.schema import simulation_error

__all__ = ["SERIES_SUFFIXES", "XdmfSeries", "is_series_file", "read_pvd", "read_xdmf_series",
           "series_dt"]

SERIES_SUFFIXES = (".pvd", ".xdmf", ".xmf")


def _xml_root(path: Path, name: str) -> ET.Element:
    try:
        return ET.parse(path).getroot()
    except (ET.ParseError, OSError) as err:
        raise simulation_error(path, name, "mesh", f"cannot read: {err}") from err


def _temporal_grid(root: ET.Element) -> ET.Element | None:
    for grid in root.iter("Grid"):
        if grid.get("GridType") == "Collection" and grid.get("CollectionType") == "Temporal":
            return grid
    return None


def is_series_file(source) -> bool:
    """True for one ``.pvd`` file, or one XDMF file holding a temporal collection."""
    if isinstance(source, list | tuple):
        return False
    path = Path(source)
    if not path.is_file() or path.suffix.lower() not in SERIES_SUFFIXES:
        return False
    if path.suffix.lower() == ".pvd":
        return True
    try:
        return _temporal_grid(ET.parse(path).getroot()) is not None
    except (ET.ParseError, OSError):
        return False


def read_pvd(path: str | os.PathLike, name: str) -> tuple[np.ndarray, list[Path]]:
    """``(times [T], mesh files)`` of a ``.pvd`` collection, in time order."""
    path = Path(path)
    root = _xml_root(path, name)
    if root.tag != "VTKFile" or root.get("type") != "Collection":
        raise simulation_error(path, name, "mesh", "not a ParaView collection (expected "
                               "<VTKFile type=\"Collection\">)")
    entries = []
    for item in root.iter("DataSet"):
        if item.get("file") is None:
            raise simulation_error(path, name, "mesh", "a <DataSet> has no 'file'")
        try:
            t = float(item.get("timestep", len(entries)))
        except ValueError as err:
            raise simulation_error(path, name, "times", f"bad timestep "
                                   f"{item.get('timestep')!r}") from err
        entries.append((t, item.get("part", "0"), path.parent / item.get("file")))
    if not entries:
        raise simulation_error(path, name, "frames", "the collection lists no <DataSet>")
    if len({part for _, part, _ in entries}) > 1:
        raise simulation_error(path, name, "mesh", "several parts per time step (multi-block); "
                               "write one mesh per time step")
    entries.sort(key=lambda e: e[0])
    times = np.array([t for t, _, _ in entries], np.float64)
    if np.any(np.diff(times) == 0):
        repeated = times[np.argmin(np.diff(times))]
        raise simulation_error(path, name, "times", f"repeated timestep {repeated}")
    missing = [str(f) for _, _, f in entries if not f.is_file()]
    if missing:
        raise simulation_error(path, name, "frames", f"missing mesh file(s) {missing[:3]}")
    return times, [f for _, _, f in entries]


@dataclass(frozen=True)
class XdmfSeries:
    """An XDMF time series: the first step's mesh, every step's points and the times."""

    mesh: object  # meshio.Mesh of the first step (points, cells, point data)
    positions: np.ndarray  # [T, N, 3] float32
    times: np.ndarray  # [T] float64


def _data_item(item: ET.Element, folder: Path, path: Path, name: str) -> np.ndarray:
    """An XDMF ``DataItem`` in XML or HDF format (``file.h5:/dataset``)."""
    dims = [int(d) for d in item.get("Dimensions", "").split()]
    fmt = item.get("Format", "XML")
    text = (item.text or "").strip()
    if fmt == "XML":
        return np.array(text.split(), np.float64).reshape(dims)
    if fmt == "HDF":
        import h5py

        file, _, inner = text.partition(":")
        try:
            with h5py.File(folder / file, "r") as f:
                return np.asarray(f[inner][()]).reshape(dims)
        except (OSError, KeyError) as err:
            raise simulation_error(path, name, "positions", f"cannot read {text}: {err}") from err
    raise simulation_error(path, name, "positions", f"unsupported XDMF data format '{fmt}'")


def read_xdmf_series(path: str | os.PathLike, name: str) -> XdmfSeries:
    """Read an XDMF temporal collection (module docstring)."""
    import meshio

    path = Path(path)
    grids = list(_temporal_grid(_xml_root(path, name)) or [])
    try:
        with meshio.xdmf.TimeSeriesReader(str(path)) as reader:
            points, cells = reader.read_points_cells()
            steps = [reader.read_data(k) for k in range(reader.num_steps)]
    except Exception as err:  # meshio parsers raise many types: all mean a bad input file
        msg = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise simulation_error(path, name, "mesh", f"cannot read: {msg}") from err
    if not steps:
        raise simulation_error(path, name, "frames", "the temporal collection is empty")
    points = np.asarray(points, np.float64)
    positions = np.empty((len(steps), *points.shape), np.float32)
    for k, (_, point_data, _) in enumerate(steps):
        geometry = grids[k].find("Geometry") if k < len(grids) else None
        if "position" in point_data:
            frame = np.asarray(point_data["position"])
        elif geometry is not None and geometry.find("DataItem") is not None:
            frame = _data_item(geometry.find("DataItem"), path.parent, path, name)
        else:
            frame = points
        if frame.shape != points.shape:
            raise simulation_error(path, name, "positions", f"step {k} has points of shape "
                                   f"{frame.shape}, the first step {points.shape}")
        positions[k] = frame
    first = {k: v for k, v in steps[0][1].items() if k != "position"}
    mesh = meshio.Mesh(points, cells, point_data=first)
    return XdmfSeries(mesh, positions, np.array([t for t, _, _ in steps], np.float64))


def series_dt(times: np.ndarray, dt: float | None, path, name: str) -> float | None:
    """The frame spacing of ``times`` (uniform within 1e-6 relative), checked against ``dt``.

    Returns ``dt`` when given and consistent, the spacing when ``dt`` is None, and None for a
    single frame. Raises when the times are not uniform (give frames at a constant ``dt``) or
    disagree with a given ``dt``.
    """
    if len(times) < 2:
        return dt
    steps = np.diff(np.asarray(times, np.float64))
    spacing = float(steps.mean())
    if np.abs(steps - spacing).max() > 1e-6 * abs(spacing):
        raise simulation_error(path, name, "times", f"frames are not evenly spaced in time "
                               f"(steps from {steps.min():.6g} to {steps.max():.6g})")
    if dt is not None and abs(dt - spacing) > 1e-6 * abs(spacing):
        raise simulation_error(path, name, "dt", f"--dt {dt:g} disagrees with the file's times "
                               f"(one frame every {spacing:.6g})")
    return spacing if dt is None else dt
