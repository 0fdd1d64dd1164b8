"""Export: XDMF time series (moving points, node types) and VTU + PVD series."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import h5py
import meshio
import numpy as np
import pytest

from thrombojax.errors import ConfigError, DatasetError
from thrombojax.io.export import export_trajectory
from thrombojax.types import NodeType


def _traj(t=3):
    pos = np.zeros((t, 6, 3), np.float32)
    pos[:, :4] = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
    pos[:, 4:] = [[2, 0, 0], [2, 1, 0]]
    pos[:, :4, 0] += np.arange(t)[:, None] * 0.5  # the clot tet moves along x
    node_type = np.array([NodeType.CLOT] * 4 + [NodeType.VESSEL] * 2)
    return pos, node_type, np.array([[0, 1, 2, 3]])


def test_xdmf_series_has_moving_geometry_and_node_types(tmp_path):
    pos, node_type, tets = _traj()
    err = np.arange(18, dtype=np.float32).reshape(3, 6)
    path = export_trajectory(tmp_path / "run.xdmf", pos, node_type, clot_cells=tets, dt=0.1,
                             point_data={"error": err})
    assert path.suffix == ".xdmf"
    grids = ET.parse(path).getroot().findall("./Domain/Grid/Grid")
    assert [float(g.find("Time").get("Value")) for g in grids] == pytest.approx([0, 0.1, 0.2])
    names = {a.get("Name") for a in grids[0].findall("Attribute")}
    assert names == {"position", "node_type", "displacement", "error"}
    assert grids[1].find("Topology").get("NumberOfElements") == "3"  # 1 tet + 2 vertex cells
    with h5py.File(tmp_path / "run.xdmf.h5") as f:
        ref = grids[2].find("Geometry/DataItem").text.split(":")[1]
        np.testing.assert_array_equal(f[ref][()], pos[2])
        np.testing.assert_array_equal(f["static/node_type"][()], node_type)
        # mixed topology: [6, tet...] then [1, 1, node] per loose node
        np.testing.assert_array_equal(f["topology"][()], [6, 0, 1, 2, 3, 1, 1, 4, 1, 1, 5])
        np.testing.assert_allclose(f["fields/displacement/00002"][()][0], [1.0, 0, 0])
    # an independent reader agrees (meshio misreads XDMF polyvertex counts, so cover all nodes)
    path = export_trajectory(tmp_path / "cells.xdmf", pos, node_type, clot_cells=tets,
                             wall_cells=[[3, 4, 5]], dt=0.1, point_data={"error": err})
    reader = meshio.xdmf.TimeSeriesReader(path)
    points, cells = reader.read_points_cells()
    np.testing.assert_allclose(points, pos[0])
    assert [(c.type, len(c.data)) for c in cells] == [("tetra", 1), ("triangle", 1)]
    t, point_data, _ = reader.read_data(1)
    assert t == pytest.approx(0.1) and point_data["error"].tolist() == err[1].tolist()


def test_vtu_series_and_errors(tmp_path):
    pos, node_type, tets = _traj()
    pvd = export_trajectory(tmp_path / "sim", pos, node_type, clot_cells=tets, format="vtu")
    files = [d.get("file") for d in ET.parse(pvd).getroot().iter("DataSet")]
    assert len(files) == 3
    mesh = meshio.read(tmp_path / files[-1])
    np.testing.assert_allclose(mesh.points, pos[-1])
    np.testing.assert_array_equal(mesh.point_data["node_type"], node_type)
    assert {c.type for c in mesh.cells} == {"tetra", "vertex"}
    with pytest.raises(ConfigError):
        export_trajectory(tmp_path / "x", pos, node_type, format="obj")
    with pytest.raises(DatasetError):
        export_trajectory(tmp_path / "x", pos, node_type, clot_cells=[[0, 1, 2, 9]])
    with pytest.raises(DatasetError):
        export_trajectory(tmp_path / "x", pos, node_type, point_data={"e": np.ones((2, 6))})


def test_export_file_exports_dataset_simulations(tmp_path):
    from thrombojax.io.export import export_file
    from thrombojax.io.hdf5 import Simulation, write_dataset

    pos, node_type, tets = _traj()
    sims = [Simulation(name=f"sim_{i}", positions=pos + i, node_type=node_type.astype(np.int8),
                       clot_cells=tets.astype(np.int32), attrs={"dt": 0.5}) for i in range(2)]
    src = write_dataset(tmp_path / "d.h5", sims, name="t", source="test")
    paths = export_file(src, tmp_path / "out", names=["sim_1"], format="vtu")
    assert [p.name for p in paths] == ["sim_1.pvd"]
    assert len(export_file(src, tmp_path / "all")) == 2
    with pytest.raises(DatasetError, match="sim_9"):
        export_file(src, tmp_path / "out", names=["sim_9"])
