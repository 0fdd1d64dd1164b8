"""Imports a solver user needs: Abaqus reference nodes and membrane/surface walls, Abaqus
labels in messages, single-file time series (.pvd, XDMF) and a round trip through export."""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
from dataset_factory import make_simulation

from thrombojax.cli import main
from thrombojax.errors import DatasetError
from thrombojax.io.abaqus import read_abaqus
from thrombojax.io.export import export_simulation, export_trajectory
from thrombojax.io.hdf5 import open_dataset, write_dataset
from thrombojax.io.meshio_import import read_mesh_series
from thrombojax.io.series_file import series_dt

LABELS = 100 + 7 * np.arange(13)  # non-contiguous Abaqus node labels
REF_LABEL = 5000  # a rigid body's reference node: in a node set, in no element


def write_inp(path, sim, *, wall_type="SFM3D3", quads=False, ref=True, sets=True):
    """A flat .inp: C3D4 clot, membrane/surface wall elements, optionally a reference node."""
    lines = ["*Heading", "*Node"]
    coords = sim.positions[0].astype(np.float64).tolist()
    rows = [f"{lab}, {x!r}, {y!r}, {z!r}" for lab, (x, y, z) in zip(LABELS, coords, strict=True)]
    if ref:
        rows.insert(5, f"{REF_LABEL}, 0.5, 0.0, 0.0")  # between clot and wall nodes
    lines += rows
    lines.append("*Element, type=C3D4" + (", elset=CLOT" if sets else ""))
    lines += [f"{1 + i}, " + ", ".join(str(LABELS[n]) for n in c)
              for i, c in enumerate(sim.clot_cells)]
    lines.append(f"*Element, type={wall_type}" + (", elset=VESSEL_WALL" if sets else ""))
    walls = sim.wall_cells
    if quads:  # pairs of triangles [a, b, c], [b, d, c] -> quad [a, b, d, c]
        walls = [[t1[0], t1[1], t2[1], t1[2]] for t1, t2 in zip(walls[::2], walls[1::2],
                                                                 strict=True)]
    lines += [f"{10 + i}, " + ", ".join(str(LABELS[n]) for n in c) for i, c in enumerate(walls)]
    if ref:
        lines += ["*Nset, nset=RP", str(REF_LABEL)]
    lines += ["*Step", "*Static", "*End Step"]
    path.write_text("\n".join(lines) + "\n")
    return path


def _with_ref_rows(positions):
    """Frames listing every .inp node (the reference node's row included, in file order)."""
    ref = np.broadcast_to([0.5, 0.0, 0.0], (positions.shape[0], 1, 3))
    return np.concatenate([positions[:, :5], ref, positions[:, 5:]], axis=1)


def _same(got, src):
    np.testing.assert_array_equal(got.positions, src.positions)
    np.testing.assert_array_equal(got.node_type, src.node_type)
    np.testing.assert_array_equal(got.clot_cells, src.clot_cells)


def test_reference_node_is_dropped_and_surface_walls_accepted(tmp_path):
    src = make_simulation("a", n_frames=3)
    inp = write_inp(tmp_path / "m.inp", src)
    np.save(tmp_path / "all.npy", _with_ref_rows(src.positions))  # frames with the ref node
    np.save(tmp_path / "kept.npy", src.positions)  # frames without it
    for frames in ("all.npy", "kept.npy"):
        sim = read_abaqus(inp, tmp_path / frames)
        _same(sim, src)
        np.testing.assert_array_equal(sim.wall_cells, src.wall_cells)
        assert sim.attrs["dropped_node_labels"] == str(REF_LABEL)
    for sets in (True, False):  # element types alone decide, too
        _same(read_abaqus(write_inp(tmp_path / "n.inp", src, wall_type="M3D3", sets=sets),
                          tmp_path / "all.npy"), src)
    with pytest.raises(DatasetError, match=r"shape \(3, 12, 3\), expected \[frames, 14 or 13"):
        np.save(tmp_path / "short.npy", src.positions[:, :12])
        read_abaqus(inp, tmp_path / "short.npy")


@pytest.mark.parametrize("wall_type", ["SFM3D4", "M3D4R", "R3D4", "S4R"])
def test_quad_wall_elements_become_triangles(tmp_path, wall_type):
    src = make_simulation("a", n_frames=2)
    inp = write_inp(tmp_path / "q.inp", src, wall_type=wall_type, quads=True, ref=False)
    np.save(tmp_path / "f.npy", src.positions)
    sim = read_abaqus(inp, tmp_path / "f.npy")
    _same(sim, src)
    assert sim.wall_cells.shape == (8, 3)
    assert set(np.unique(sim.wall_cells)) == set(np.unique(src.wall_cells))


def test_clot_set_alone_makes_the_rest_vessel_and_errors_name_labels(tmp_path):
    src = make_simulation("a", n_frames=3)
    inp = write_inp(tmp_path / "m.inp", src)
    # a set named like a vessel set that covers only some wall nodes: ignored with --clot-set
    text = inp.read_text().replace("*Step", "*Nset, nset=VESSEL_INLET\n" + str(LABELS[6])
                                   + "\n*Step")
    inp.write_text(text)
    np.save(tmp_path / "f.npy", src.positions)
    _same(read_abaqus(inp, tmp_path / "f.npy", clot_sets=["clot"]), src)
    with pytest.raises(DatasetError, match=f"node label {LABELS[5]} is in no clot set"):
        read_abaqus(inp, tmp_path / "f.npy", vessel_sets=["VESSEL_INLET"])
    moved = src.positions.copy()
    moved[2, 6] += 0.1  # wall node index 6 (label LABELS[6]) moves
    np.save(tmp_path / "moved.npy", moved)
    with pytest.raises(DatasetError, match=f"vessel node label {LABELS[6]} moves"):
        read_abaqus(inp, tmp_path / "moved.npy")


def test_pvd_series_import(tmp_path):
    src = make_simulation("run", n_frames=4)
    pvd = export_simulation(src, tmp_path / "run", format="vtu")
    sim = read_mesh_series(pvd)
    assert sim.name == "run" and sim.attrs["dt"] == pytest.approx(0.01)
    np.testing.assert_allclose(sim.positions, src.positions, atol=1e-6)
    np.testing.assert_array_equal(sim.node_type, src.node_type)
    np.testing.assert_array_equal(sim.wall_cells, src.wall_cells)
    with pytest.raises(DatasetError, match="field 'dt': --dt 0.5 disagrees"):
        read_mesh_series(pvd, attrs={"dt": 0.5})


def test_xdmf_round_trip_through_export_and_import(tmp_path, capsys):
    sims = [make_simulation(f"sim_{i}", n_frames=5, seed=i) for i in range(2)]
    data = write_dataset(tmp_path / "d.h5", sims, name="d", source="tests", units="mm")
    assert main(["export", str(data), "--out", str(tmp_path / "ex")]) == 0
    series = [str(tmp_path / "ex" / f"sim_{i}.xdmf") for i in range(2)]
    out = tmp_path / "back.h5"
    assert main(["import", "vtu", *series, "--out", str(out), "--units", "mm", "--quiet"]) == 0
    back = open_dataset(out)
    assert back.names == ["sim_0", "sim_1"] and back.attrs["units"] == "mm"
    for src in sims:
        got = back[src.name]
        np.testing.assert_allclose(got.positions, src.positions, atol=1e-6)
        np.testing.assert_array_equal(got.node_type, src.node_type)
        np.testing.assert_array_equal(got.clot_cells, src.clot_cells)
        assert got.attrs["dt"] == pytest.approx(0.01)
    # meshio's time-series reader sees the moving points through the 'position' array
    with meshio.xdmf.TimeSeriesReader(series[1]) as reader:
        reader.read_points_cells()
        t, point_data, _ = reader.read_data(4)
    assert t == pytest.approx(0.04)
    np.testing.assert_allclose(point_data["position"], sims[1].positions[4])


def test_rollout_series_times_start_at_its_first_frame(tmp_path):
    src = make_simulation("r", n_frames=6)
    late = dataclasses.replace(src, positions=src.positions[3:], attrs={**src.attrs,
                                                                         "first_frame": 3})
    sim = read_mesh_series(export_simulation(late, tmp_path / "late"))
    assert sim.attrs["dt"] == pytest.approx(0.01)
    path = export_trajectory(tmp_path / "t", src.positions, src.node_type, dt=0.01,
                             first_frame=3, format="vtu")
    times = [float(d.get("timestep")) for d in ET.parse(path).getroot().iter("DataSet")]
    assert times == pytest.approx((3 + np.arange(6)) * 0.01)


def test_series_dt_checks_even_spacing():
    assert series_dt(np.array([0.0, 0.5, 1.0]), None, "f", "s") == pytest.approx(0.5)
    assert series_dt(np.array([0.0]), None, "f", "s") is None
    with pytest.raises(DatasetError, match="not evenly spaced"):
        series_dt(np.array([0.0, 0.5, 1.5]), None, "f", "s")


def test_xdmf_with_vertex_cells_and_meshio_time_series_files(tmp_path, monkeypatch):
    src = make_simulation("v", n_frames=3)
    # no wall cells: the wall nodes become XDMF polyvertex cells (which meshio misreads)
    path = export_trajectory(tmp_path / "v", src.positions, src.node_type,
                             clot_cells=src.clot_cells, dt=0.1)
    sim = read_mesh_series(path)
    np.testing.assert_array_equal(sim.positions, src.positions)
    np.testing.assert_array_equal(sim.node_type, src.node_type)
    assert sim.wall_cells is None and sim.attrs["dt"] == pytest.approx(0.1)
    # meshio's writer: one mesh grid outside the collection, steps include it (fixed points)
    monkeypatch.chdir(tmp_path)  # meshio writes the .h5 into the working directory
    fixed = tmp_path / "fixed.xdmf"
    with meshio.xdmf.TimeSeriesWriter(fixed) as writer:
        writer.write_points_cells(src.positions[0].astype(np.float64),
                                  [("tetra", src.clot_cells), ("triangle", src.wall_cells)])
        for t in (0.0, 0.5, 1.0):
            writer.write_data(t, point_data={"kind": src.node_type.astype(np.int32)})
    sim = read_mesh_series(fixed, node_type_array="kind")
    assert sim.name == "fixed" and sim.attrs["dt"] == pytest.approx(0.5)
    np.testing.assert_array_equal(sim.positions, np.repeat(src.positions[:1], 3, axis=0))
    np.testing.assert_array_equal(sim.wall_cells, src.wall_cells)


def test_vtu_series_with_quad_wall_cells(tmp_path):
    src = make_simulation("q", n_frames=2)
    walls = src.wall_cells
    quads = np.array([[t1[0], t1[1], t2[1], t1[2]] for t1, t2 in zip(walls[::2], walls[1::2],
                                                                       strict=True)])
    folder = tmp_path / "q"
    folder.mkdir()
    for t, frame in enumerate(src.positions):
        meshio.write(folder / f"f{t}.vtu",
                     meshio.Mesh(frame, [("tetra", src.clot_cells), ("quad", quads)]))
    sim = read_mesh_series(folder)
    np.testing.assert_array_equal(sim.node_type, src.node_type)
    assert sim.wall_cells.shape == (8, 3)
