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
from pathlib import Path

import numpy as np

from thrombojax.io.schema import simulation_error
from thrombojax.io.xdmf_read import read_xdmf_temporal

__all__ = ["SERIES_SUFFIXES", "is_series_file", "read_pvd", "read_xdmf_series", "series_dt"]

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


def read_xdmf_series(path: str | os.PathLike, name: str):
    """Read an XDMF temporal collection (:mod:`thrombojax.io.xdmf_read`).

    Returns:
        ``(mesh, positions, times)``: a ``meshio.Mesh`` of the first step (its points, cells
        and node arrays), ``[T, N, 3]`` float32 points of every step, ``[T]`` times.
    """
    import meshio

    path = Path(path)
    root = _xml_root(path, name)
    collection, domain = _temporal_grid(root), root.find("Domain")
    if collection is None or domain is None:
        raise simulation_error(path, name, "mesh", "no temporal collection in a Domain")
    series = read_xdmf_temporal(path, collection, domain, name)
    mesh = meshio.Mesh(series.positions[0], series.cells, point_data=series.point_data)
    return mesh, series.positions, series.times


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
