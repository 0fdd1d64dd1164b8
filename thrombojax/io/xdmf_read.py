"""A small reader of XDMF 3 temporal collections with moving points (what meshio cannot read).

meshio reads a temporal collection only through ``meshio.xdmf.TimeSeriesReader``, which returns
the points of one grid (not of every step) and reads a ``Mixed`` topology's polyvertex cells
without their node count (the XDMF layout is ``1, n, node...``), so it fails on files that hold
vertex cells, such as ``thrombojax export`` writes for nodes outside every tetrahedron and
triangle. This reader follows the XDMF layout:

- the collection is the ``Grid`` with ``CollectionType="Temporal"``; each child grid is one step
  with its ``Time``, its ``Geometry`` (``XYZ``) and its node-centred ``Attribute`` arrays;
- a step without its own ``Topology`` / ``Geometry`` uses those of the mesh grid: a uniform
  grid directly in the ``Domain`` (meshio's ``TimeSeriesWriter`` layout), else the first step;
- ``DataItem`` formats ``XML`` and ``HDF`` (``file.h5:/path``, relative to the ``.xdmf``);
- topologies: ``Mixed`` (vertex/polyvertex, line/polyline, triangle, quad, tetrahedron,
  pyramid, wedge, hexahedron, and the 6/8/9/10-node triangle/quad/tetrahedron) or one named type.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from thrombojax.io.schema import simulation_error

__all__ = ["XdmfSeries", "read_xdmf_temporal"]

# Mixed-topology type ids (XDMF): -> (meshio name, nodes per cell; None: a count follows)
_MIXED = {1: ("vertex", None), 2: ("line", None), 4: ("triangle", 3), 5: ("quad", 4),
          6: ("tetra", 4), 7: ("pyramid", 5), 8: ("wedge", 6), 9: ("hexahedron", 8),
          0x23: ("quad9", 9), 0x24: ("triangle6", 6), 0x25: ("quad8", 8), 0x26: ("tetra10", 10)}
_NAMED = {"polyvertex": ("vertex", 1), "polyline": ("line", 2), "triangle": ("triangle", 3),
          "quadrilateral": ("quad", 4), "tetrahedron": ("tetra", 4), "pyramid": ("pyramid", 5),
          "wedge": ("wedge", 6), "hexahedron": ("hexahedron", 8),
          "triangle_6": ("triangle6", 6), "quadrilateral_8": ("quad8", 8),
          "quadrilateral_9": ("quad9", 9), "tetrahedron_10": ("tetra10", 10)}


@dataclass(frozen=True)
class XdmfSeries:
    """An XDMF time series.

    Attributes:
        cells: ``[(meshio cell type, [n, k] int node indices)]`` of the first step.
        point_data: the first step's node arrays (``position`` excluded).
        positions: ``[T, N, 3]`` float32 points of every step. times: ``[T]`` float64.
    """
    cells: list
    point_data: dict
    positions: np.ndarray
    times: np.ndarray


def _data_item(item, folder: Path, path: Path, name: str, field: str) -> np.ndarray:
    if item is None:
        raise simulation_error(path, name, field, "an XDMF element without a DataItem")
    dims = [int(d) for d in item.get("Dimensions", "").split()]
    fmt = item.get("Format", "XML")
    text = (item.text or "").strip()
    try:
        if fmt == "XML":
            return np.array(text.split(), np.float64).reshape(dims)
        if fmt == "HDF":

            file, _, inner = text.partition(":")
            with h5py.File(folder / file, "r") as f:
                return np.asarray(f[inner][()]).reshape(dims)
    except (OSError, KeyError, ValueError) as err:
        raise simulation_error(path, name, field, f"cannot read DataItem {text!r}: "
                               f"{err}") from err
    raise simulation_error(path, name, field, f"unsupported XDMF data format '{fmt}'")


def _mixed_cells(data: np.ndarray, path: Path, name: str) -> list:
    data = np.asarray(data, np.int64).ravel()
    blocks: dict[str, list] = {}
    r = 0
    while r < data.size:
        code = int(data[r])
        if code not in _MIXED:
            raise simulation_error(path, name, "mesh", f"unsupported XDMF cell type id {code}")
        kind, n = _MIXED[code]
        if n is None:  # polyvertex / polyline: a node count follows the type id
            count = int(data[r + 1])
            nodes = data[r + 2:r + 2 + count]
            r += 2 + count
            if kind == "vertex":
                blocks.setdefault(kind, []).extend([[v] for v in nodes])
            else:
                blocks.setdefault(kind, []).extend(np.stack([nodes[:-1], nodes[1:]], 1).tolist())
        else:
            blocks.setdefault(kind, []).append(data[r + 1:r + 1 + n].tolist())
            r += 1 + n
    return [(kind, np.asarray(cells, np.int64)) for kind, cells in blocks.items()]


def _topology(topo, folder: Path, path: Path, name: str) -> list:
    kind = (topo.get("TopologyType") or topo.get("Type") or "").lower()
    data = _data_item(topo.find("DataItem"), folder, path, name, "mesh")
    if kind == "mixed":
        return _mixed_cells(data, path, name)
    if kind not in _NAMED:
        raise simulation_error(path, name, "mesh", f"unsupported XDMF topology '{kind}'")
    cell, n = _NAMED[kind]
    return [(cell, np.asarray(data, np.int64).reshape(-1, n))]


def _child(grid, mesh_grid, tag: str):
    found = grid.find(tag)
    return found if found is not None else mesh_grid.find(tag)


def read_xdmf_temporal(path: str | os.PathLike, collection, domain, name: str) -> XdmfSeries:
    """Read the temporal ``collection`` grid of the XDMF file ``path`` (module docstring).

    Args:
        path: the ``.xdmf``. collection: its temporal ``Grid`` element. domain: its ``Domain``.
        name: simulation name (for messages).
    """
    path = Path(path)
    folder = path.parent
    steps = [g for g in collection if g.tag == "Grid"]
    if not steps:
        raise simulation_error(path, name, "frames", "the temporal collection is empty")
    outer = [g for g in domain if g.tag == "Grid" and g.get("GridType", "Uniform") == "Uniform"]
    mesh_grid = outer[0] if outer else steps[0]
    topo = _child(steps[0], mesh_grid, "Topology")
    if topo is None:
        raise simulation_error(path, name, "mesh", "no Topology")
    cells = _topology(topo, folder, path, name)
    frames, times, first_data = [], [], {}
    for k, grid in enumerate(steps):
        time = grid.find("Time")
        if time is None or time.get("Value") is None:
            raise simulation_error(path, name, "times", f"step {k} has no <Time Value=...>")
        times.append(float(time.get("Value")))
        geometry = _child(grid, mesh_grid, "Geometry")
        if geometry is None:
            raise simulation_error(path, name, "positions", f"step {k} has no Geometry")
        if geometry.get("GeometryType", "XYZ") not in ("XYZ",):
            raise simulation_error(path, name, "positions", "only XYZ geometry is supported, "
                                   f"got '{geometry.get('GeometryType')}'")
        points = _data_item(geometry.find("DataItem"), folder, path, name, "positions")
        if frames and points.shape != frames[0].shape:
            raise simulation_error(path, name, "positions", f"step {k} has points of shape "
                                   f"{points.shape}, the first step {frames[0].shape}")
        frames.append(points.reshape(-1, 3))
        if k == 0:
            first_data = {a.get("Name"): _data_item(a.find("DataItem"), folder, path, name,
                                                    a.get("Name"))
                          for a in grid.findall("Attribute")
                          if a.get("Center", "Node") == "Node" and a.get("Name") != "position"}
    return XdmfSeries(cells, first_data, np.stack(frames).astype(np.float32),
                      np.asarray(times, np.float64))
