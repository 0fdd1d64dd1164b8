"""Export trajectories (dataset simulations or rollouts) for ParaView: XDMF or a VTU series.

Two formats, both a time series with moving points and per-node data:

- ``"xdmf"``: ``<name>.xdmf`` (XDMF 3 XML, a temporal collection of grids) beside
  ``<name>.xdmf.h5`` holding one geometry array per frame, one shared topology and the point
  data (never ``<name>.h5``: that is the usual name of the dataset being exported).
  Written by hand rather than with ``meshio.xdmf.TimeSeriesWriter`` because that writer stores
  the points once, and our points move.
- ``"vtu"``: ``<name>/frame_0000.vtu ...`` (meshio) plus ``<name>.pvd``, the collection file
  ParaView opens as a time series.

Every file is written atomically, an existing one is replaced only with ``force=True``, the
input file is never a target, and file names come from :func:`thrombojax.io.outputs.safe_stems`
(simulation names with dots, slashes or Windows reserved names cannot collide or escape).

Times are physical: frame ``k`` of a series whose first frame is simulation frame ``first_frame``
is written at ``t = (first_frame + k) * dt`` (``dt`` from the simulation's attributes), so a
rollout (which starts at frame ``t0 - 1``) and the exported ground truth (from frame 0) play in
step when ParaView opens them together.

Readers: ParaView and VTK read both formats (XDMF with the "XDMF Reader" / ``vtkXdmfReader``,
the ``.pvd`` natively). ``meshio.read`` reads one mesh, not a time series: it stops at the XDMF
collection ("Unknown section 'Grid'"), so with meshio either read the VTU files of the ``"vtu"``
series one by one (the universally readable option), or use ``meshio.xdmf.TimeSeriesReader``:
it returns the points of the first frame only, so every XDMF frame also carries the
``position`` point array (the frame's points, no extra storage); it misreads vertex cells, so
it reads only files whose nodes are all in tetrahedra or triangles. ``thrombojax import vtu``
reads both back (:mod:`thrombojax.io.series_file`).

Cells: clot tetrahedra and wall triangles when the simulation has them (and every index is
kept), plus one vertex cell per node that no cell covers, so every node is visible. Point data:
``node_type`` (int, :class:`~thrombojax.types.NodeType`), ``displacement`` from frame 0 and any
extra per-frame fields (e.g. the rollout error).
"""

from __future__ import annotations

import pathlib
import xml.etree.ElementTree as ET

import h5py
import numpy as np

from thrombojax.errors import ConfigError, DatasetError
from thrombojax.io.outputs import atomic_path, atomic_write_text, check_targets, safe_stems

__all__ = ["EXPORT_FORMATS", "export_trajectory", "export_simulation", "export_file"]

EXPORT_FORMATS: tuple[str, ...] = ("xdmf", "vtu")

# XDMF mixed-topology type ids (XDMF spec): polyvertex 1, triangle 4, tetrahedron 6.
_XDMF_ID = {"vertex": 1, "triangle": 4, "tetra": 6}


def _cell_blocks(n_nodes: int, clot_cells, wall_cells) -> list[tuple[str, np.ndarray]]:
    blocks = []
    covered = np.zeros(n_nodes, bool)
    for kind, cells in (("tetra", clot_cells), ("triangle", wall_cells)):
        if cells is not None and len(cells):
            cells = np.asarray(cells, np.int64)
            if cells.min() < 0 or cells.max() >= n_nodes:
                raise DatasetError(f"export: {kind} cells index nodes outside 0..{n_nodes - 1}")
            blocks.append((kind, cells))
            covered[cells.ravel()] = True
    loose = np.flatnonzero(~covered)
    if loose.size:
        blocks.append(("vertex", loose[:, None]))
    return blocks


def _point_fields(positions: np.ndarray, node_type: np.ndarray, extra: dict | None):
    disp = positions - positions[:1]
    fields = {"displacement": disp.astype(np.float32)}
    for key, value in (extra or {}).items():
        value = np.asarray(value, np.float32)
        if value.shape[:2] != positions.shape[:2]:
            raise DatasetError(
                f"export: point field '{key}' has shape {value.shape}, expected "
                f"{positions.shape[:2]} (+ optional components)"
            )
        fields[key] = value
    return {"node_type": np.asarray(node_type, np.int32)}, fields


def _data_item(parent, h5_name: str, path: str, arr: np.ndarray) -> None:
    kind = "Int" if np.issubdtype(arr.dtype, np.integer) else "Float"
    item = ET.SubElement(parent, "DataItem", Dimensions=" ".join(map(str, arr.shape)),
                         NumberType=kind, Precision=str(arr.dtype.itemsize), Format="HDF")
    item.text = f"{h5_name}:{path}"


def _targets(out: pathlib.Path, format: str) -> tuple[pathlib.Path, pathlib.Path]:
    """(file ParaView opens, its companion: data file or frames folder) for a stem path."""
    if out.suffix.lower() in (".xdmf", ".pvd"):
        out = out.with_name(out.name[: -len(out.suffix)])
    if format == "xdmf":
        return out.with_name(out.name + ".xdmf"), out.with_name(out.name + ".xdmf.h5")
    return out.with_name(out.name + ".pvd"), out


def _write_xdmf(out: pathlib.Path, positions, times, blocks, static, fields) -> pathlib.Path:
    xdmf, h5_path = _targets(out, "xdmf")
    topo = np.concatenate([
        np.hstack([np.full((c.shape[0], 1), _XDMF_ID[k])]
                  + ([np.ones((c.shape[0], 1), np.int64)] if k == "vertex" else []) + [c]).ravel()
        for k, c in blocks
    ]).astype(np.int64)
    n_cells = sum(c.shape[0] for _, c in blocks)
    with atomic_path(h5_path) as tmp, h5py.File(tmp, "w") as f:
        f["topology"] = topo
        for key, value in static.items():
            f[f"static/{key}"] = value
        for t in range(positions.shape[0]):
            f[f"geometry/{t:05d}"] = positions[t].astype(np.float32)
            for key, value in fields.items():
                f[f"fields/{key}/{t:05d}"] = value[t]
    root = ET.Element("Xdmf", Version="3.0")
    series = ET.SubElement(ET.SubElement(root, "Domain"), "Grid", Name="trajectory",
                           GridType="Collection", CollectionType="Temporal")
    for t in range(positions.shape[0]):
        grid = ET.SubElement(series, "Grid", Name=f"frame_{t:05d}", GridType="Uniform")
        ET.SubElement(grid, "Time", Value=repr(float(times[t])))
        top = ET.SubElement(grid, "Topology", TopologyType="Mixed", NumberOfElements=str(n_cells))
        _data_item(top, h5_path.name, "/topology", topo)
        geo = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
        _data_item(geo, h5_path.name, f"/geometry/{t:05d}", positions[t].astype(np.float32))
        items = [("position", f"/geometry/{t:05d}", positions[t].astype(np.float32))]
        items += [(k, f"/static/{k}", v) for k, v in static.items()]
        items += [(k, f"/fields/{k}/{t:05d}", v[t]) for k, v in fields.items()]
        for key, path, value in items:
            kind = "Vector" if value.ndim == 2 and value.shape[1] == 3 else "Scalar"
            attr = ET.SubElement(grid, "Attribute", Name=key, AttributeType=kind, Center="Node")
            _data_item(attr, h5_path.name, path, value)
    ET.indent(root)
    atomic_write_text(xdmf, '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode")
                      + "\n")
    return xdmf


def _write_vtu(out: pathlib.Path, positions, times, blocks, static, fields) -> pathlib.Path:
    import meshio

    pvd, folder = _targets(out, "vtu")
    root = ET.Element("VTKFile", type="Collection", version="0.1")
    coll = ET.SubElement(root, "Collection")
    with atomic_path(folder) as tmp:
        tmp.mkdir()
        for t in range(positions.shape[0]):
            data = dict(static) | {k: v[t] for k, v in fields.items()}
            mesh = meshio.Mesh(positions[t].astype(np.float64), blocks, point_data=data)
            name = f"frame_{t:05d}.vtu"
            meshio.write(tmp / name, mesh, binary=True)
            ET.SubElement(coll, "DataSet", timestep=repr(float(times[t])),
                          file=f"{folder.name}/{name}")
    ET.indent(root)
    atomic_write_text(pvd, '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode")
                      + "\n")
    return pvd


def export_trajectory(
    out: str | pathlib.Path,
    positions: np.ndarray,
    node_type: np.ndarray,
    *,
    clot_cells: np.ndarray | None = None,
    wall_cells: np.ndarray | None = None,
    dt: float = 1.0,
    point_data: dict[str, np.ndarray] | None = None,
    format: str = "xdmf",
    force: bool = True,
    inputs: tuple = (),
    first_frame: int = 0,
) -> pathlib.Path:
    """Write one trajectory as a ParaView time series.

    Args:
        out: output stem; ``.xdmf`` + ``.xdmf.h5`` (or ``.pvd`` + a frames folder) are appended
            to its name (a trailing ``.xdmf`` / ``.pvd`` is dropped first; other dots are kept).
        positions: ``[n_frames, n_nodes, 3]`` positions (physical units).
        node_type: ``[n_nodes]`` NodeType values.
        clot_cells: ``[C, 4]`` tetrahedra or None. wall_cells: ``[F, 3]`` triangles or None.
        dt: time between frames.
        point_data: extra fields ``[n_frames, n_nodes]`` or ``[n_frames, n_nodes, k]``.
        format: ``"xdmf"`` or ``"vtu"``.
        force: replace existing files (else :class:`~thrombojax.errors.OutputError`).
        inputs: files that must never be written over.
        first_frame: simulation frame of ``positions[0]``; frame ``k`` is written at time
            ``(first_frame + k) * dt``.
    Returns:
        The path ParaView opens (``.xdmf`` or ``.pvd``).
    """
    if format not in EXPORT_FORMATS:
        raise ConfigError(f"export: unknown format '{format}'; known: {', '.join(EXPORT_FORMATS)}")
    positions = np.asarray(positions, np.float32)
    if positions.ndim != 3 or positions.shape[-1] != 3:
        raise DatasetError(f"export: positions must be [T, N, 3], got {positions.shape}")
    out = pathlib.Path(out)
    check_targets(_targets(out, format), inputs=inputs, force=force, what="export")
    out.parent.mkdir(parents=True, exist_ok=True)
    blocks = _cell_blocks(positions.shape[1], clot_cells, wall_cells)
    static, fields = _point_fields(positions, node_type, point_data)
    times = (int(first_frame) + np.arange(positions.shape[0])) * float(dt)
    writer = _write_xdmf if format == "xdmf" else _write_vtu
    return writer(out, positions, times, blocks, static, fields)


def export_simulation(sim, out: str | pathlib.Path, *, format: str = "xdmf", force: bool = True,
                      inputs: tuple = ()) -> pathlib.Path:
    """Export a :class:`~thrombojax.io.hdf5.Simulation` (a dataset entry or a saved rollout).

    Times are ``(first_frame + k) * dt`` from the simulation's attributes ``dt`` and
    ``first_frame`` (0 for a dataset entry; a saved rollout records the frame it starts at).

    Args:
        sim: the simulation. out: output stem (see :func:`export_trajectory`).
        format: ``"xdmf"`` or ``"vtu"``. force, inputs: see :func:`export_trajectory`.
    Returns:
        The path ParaView opens.
    """
    return export_trajectory(
        out, sim.positions, sim.node_type, clot_cells=sim.clot_cells,
        wall_cells=sim.wall_cells, dt=float(sim.attrs.get("dt", 1.0)), format=format,
        force=force, inputs=inputs,
        first_frame=int(sim.attrs.get("first_frame", 0)),
    )


def export_file(
    path: str | pathlib.Path,
    out_dir: str | pathlib.Path,
    *,
    names: list[str] | None = None,
    format: str = "xdmf",
    force: bool = False,
    progress: bool = False,
) -> list[pathlib.Path]:
    """Export simulations of a dataset or rollout HDF5 file (both use the dataset schema).

    Args:
        path: the ``.h5`` file. out_dir: output folder (one series per simulation).
        names: simulations to export (default: all). Unknown names raise DatasetError.
        format: ``"xdmf"`` or ``"vtu"``.
        force: replace existing exports (never ``path`` itself). Every target is checked
            before the first is written.
        progress: progress bar over simulations.
    Returns:
        The written ``.xdmf`` / ``.pvd`` paths (one per simulation, named by
        :func:`~thrombojax.io.outputs.safe_stems`).
    """
    from tqdm import tqdm

    from thrombojax.io.hdf5 import open_dataset

    ds = open_dataset(path)
    chosen = list(ds.names) if not names else list(names)
    missing = [n for n in chosen if n not in ds.names]
    if missing:
        raise DatasetError(f"{path}: no simulation(s) {missing}; available: {list(ds.names)}")
    if format not in EXPORT_FORMATS:
        raise ConfigError(f"export: unknown format '{format}'; known: {', '.join(EXPORT_FORMATS)}")
    out_dir = pathlib.Path(out_dir)
    stems = safe_stems(chosen)
    targets = [t for n in chosen for t in _targets(out_dir / stems[n], format)]
    check_targets(targets, inputs=(path,), force=force, what="export")
    return [export_simulation(ds[n], out_dir / stems[n], format=format, force=True,
                              inputs=(path,))
            for n in tqdm(chosen, desc="export", unit="sim", disable=not progress)]
