"""Importers: VTU/VTK/XDMF series and Abaqus .inp + frames, built with meshio in a temp folder."""

from __future__ import annotations

import dataclasses

import meshio
import numpy as np
import pytest
from dataset_factory import make_simulation

from thrombojax.cli import main
from thrombojax.errors import ConfigError, DatasetError
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.meshio_import import (
    import_abaqus,
    import_mesh_series,
    read_abaqus,
    read_frames,
    read_mesh_series,
)

LABELS = 100 + 7 * np.arange(13)  # non-contiguous Abaqus node labels


def write_series(folder, sim, suffix=".vtu", node_type_name=None, cells=True):
    """One meshio file per frame of ``sim``."""
    folder.mkdir(parents=True, exist_ok=True)
    vertices = [("vertex", np.arange(len(sim.node_type))[:, None])]
    blocks = [("tetra", sim.clot_cells), ("triangle", sim.wall_cells)] if cells else vertices
    for t, frame in enumerate(sim.positions):
        data = {node_type_name: sim.node_type.astype(np.int32)} if node_type_name else {}
        meshio.write(folder / f"frame_{t}{suffix}", meshio.Mesh(frame, blocks, point_data=data))
    return folder


def assert_same(got, src, cells=True):
    np.testing.assert_array_equal(got.positions, src.positions)
    np.testing.assert_array_equal(got.node_type, src.node_type)
    if cells:
        np.testing.assert_array_equal(got.clot_cells, src.clot_cells)
        np.testing.assert_array_equal(got.wall_cells, src.wall_cells)


def test_vtu_series_node_type_from_cells(tmp_path):
    src = make_simulation("run", n_frames=12)  # 12 frames: natural order frame_2 < frame_10
    folder = write_series(tmp_path / "run", src)
    sim = read_mesh_series(folder, attrs={"dt": 0.01})
    assert sim.name == "run" and sim.attrs["dt"] == 0.01
    assert_same(sim, src)
    assert_same(read_mesh_series(str(folder / "frame_*.vtu"), name="g"), src)


@pytest.mark.parametrize("suffix", [".vtk", ".xdmf"])
def test_vtk_and_xdmf_series_node_type_from_point_data(tmp_path, suffix):
    src = make_simulation("run", n_frames=4)
    folder = write_series(tmp_path / "run", src, suffix=suffix, node_type_name="kind")
    assert_same(read_mesh_series(folder, node_type_array="kind"), src)
    with pytest.raises(DatasetError, match="no point-data array 'node_type'"):
        read_mesh_series(folder, node_type_array="node_type")


def test_point_data_node_type_without_cells(tmp_path):
    src = make_simulation("run", n_frames=3)
    folder = write_series(tmp_path / "run", src, node_type_name="node_type", cells=False)
    sim = read_mesh_series(folder)
    assert_same(sim, src, cells=False)
    assert sim.clot_cells is None and sim.wall_cells is None


def test_many_series_into_one_file_and_cli(tmp_path, capsys):
    sims = [make_simulation(f"r{i}", seed=i) for i in range(3)]
    folders = [str(write_series(tmp_path / s.name, s)) for s in sims]
    out = import_mesh_series(folders[:2], tmp_path / "a.h5", dt=0.5, progress=False)
    ds = open_dataset(out)
    assert ds.names == ["r0", "r1"] and ds.attrs["source"] == "meshio import"
    assert ds["r1"].attrs["dt"] == 0.5
    assert_same(ds["r1"], sims[1])
    argv = ["import", "vtu", *folders, "--out", str(tmp_path / "b.h5"), "--quiet", "--units", "mm",
            "--name", "x", "--name", "y", "--name", "z", "--reference-time", "180"]
    assert main(argv) == 0
    ds = open_dataset(tmp_path / "b.h5")
    assert ds.names == ["x", "y", "z"] and ds["z"].attrs["reference_wall_time_s"] == 180.0
    assert ds.attrs["units"] == "mm"
    assert_same(ds["z"], sims[2])
    assert main(argv) == 2  # exists, no --force
    assert "already exists" in capsys.readouterr().err
    assert main([*argv, "--force"]) == 0
    assert ds.attrs["kind"] == "unknown" and ds.attrs["skip_frames"] == 0
    assert main([*argv, "--force", "--kind", "bendvessel", "--skip-frames", "3"]) == 0
    ds = open_dataset(tmp_path / "b.h5")
    assert (ds.attrs["kind"], ds.attrs["skip_frames"]) == ("bendvessel", 3)
    one_name = ["import", "vtu", *folders, "--out", str(tmp_path / "c.h5"), "--name", "n",
                "--units", "mm"]
    assert main(one_name) == 2 and not (tmp_path / "c.h5").exists()
    assert "1 names given for 3 simulations" in capsys.readouterr().err


def write_inp(path, sim, *, clot_set="CLOT", wall_set="VESSEL_WALL", nset=None):
    """A flat Abaqus input file with labelled nodes, C3D4 clot and S3R wall elements."""
    lines = ["*Heading", "** written by the thrombojax tests", "*Node"]
    coords = sim.positions[0].astype(np.float64).tolist()
    lines += [f"{lab}, {x!r}, {y!r}, {z!r}" for lab, (x, y, z) in zip(LABELS, coords, strict=True)]
    elset = f", elset={clot_set}" if clot_set else ""
    lines.append(f"*Element, type=C3D4{elset}")
    lines += [f"{1 + i}, " + ", ".join(str(LABELS[n]) for n in c)
              for i, c in enumerate(sim.clot_cells)]
    elset = f", elset={wall_set}" if wall_set else ""
    lines.append(f"*Element, type=S3R{elset}")
    lines += [f"{10 + i}, " + ", ".join(str(LABELS[n]) for n in c)
              for i, c in enumerate(sim.wall_cells)]
    if nset:
        lines += [f"*Nset, nset={nset}", ", ".join(str(v) for v in LABELS[:5])]
    lines += ["*Step", "*Static", "*End Step"]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_abaqus_frame_formats(tmp_path):
    src = make_simulation("a", n_frames=4)
    inp = write_inp(tmp_path / "m.inp", src)
    np.save(tmp_path / "all.npy", src.positions)
    npy_dir, csv_dir, lab_dir = (tmp_path / d for d in ("npy", "csv", "lab"))
    for d in (npy_dir, csv_dir, lab_dir):
        d.mkdir()
    perm = np.random.default_rng(0).permutation(13)
    for t, frame in enumerate(src.positions):
        np.save(npy_dir / f"frame_{t:04d}.npy", frame)
        np.savetxt(csv_dir / f"frame_{t:04d}.csv", frame, delimiter=",", header="x,y,z",
                   comments="", fmt="%.9g")
        rows = np.column_stack([LABELS, frame])[perm]
        np.savetxt(lab_dir / f"frame_{t:04d}.csv", rows, fmt=["%d", "%.9g", "%.9g", "%.9g"])
    for frames in ("all.npy", "npy", "csv", "lab"):
        sim = read_abaqus(inp, tmp_path / frames, attrs={"dt": 0.1})
        assert_same(sim, src)
        assert sim.attrs["dt"] == 0.1 and sim.attrs["source_inp"] == str(inp)


def test_abaqus_set_choices(tmp_path):
    src = make_simulation("a", n_frames=3)
    np.save(tmp_path / "f.npy", src.positions)
    # custom names, given explicitly (case-insensitive); vessel = all other nodes
    inp = write_inp(tmp_path / "m1.inp", src, clot_set="THROMBUS", wall_set="TUBE")
    assert_same(read_abaqus(inp, tmp_path / "f.npy", clot_sets=["thrombus"]), src)
    with pytest.raises(DatasetError, match=r"m1.inp: simulation 'f': field 'clot_sets': no set"):
        read_abaqus(inp, tmp_path / "f.npy", clot_sets=["CLOT"])
    # no matching set: element types decide; node set given explicitly
    inp = write_inp(tmp_path / "m2.inp", src, clot_set=None, wall_set=None, nset="BLOB")
    assert_same(read_abaqus(inp, tmp_path / "f.npy"), src)
    assert_same(read_abaqus(inp, tmp_path / "f.npy", clot_sets=["BLOB"]), src)
    out = import_abaqus([inp], [tmp_path / "f.npy", tmp_path / "f.npy"], tmp_path / "d.h5",
                        names=["s1", "s2"], progress=False)
    assert open_dataset(out).names == ["s1", "s2"]


def test_abaqus_inp_written_by_meshio(tmp_path):
    src = make_simulation("a", n_frames=3)
    n_tet, n_tri = len(src.clot_cells), len(src.wall_cells)
    mesh = meshio.Mesh(
        src.positions[0].astype(np.float64),
        [("tetra", src.clot_cells), ("triangle", src.wall_cells)],
        cell_sets={"Clot-1": [np.arange(n_tet), np.array([], int)],
                   "Vessel-Wall": [np.array([], int), np.arange(n_tri)]},
    )
    meshio.write(tmp_path / "m.inp", mesh, file_format="abaqus")
    folder = tmp_path / "csv"
    folder.mkdir()
    for t, frame in enumerate(src.positions):  # labels 1..N as meshio writes them
        rows = np.column_stack([np.arange(1, 14), frame])[::-1]
        np.savetxt(folder / f"frame_{t}.csv", rows, delimiter=",", fmt="%.9g",
                   header="label,x,y,z", comments="")
    assert_same(read_abaqus(tmp_path / "m.inp", folder), src)


def test_abaqus_cli(tmp_path, capsys):
    src = make_simulation("a", n_frames=3)
    inp = write_inp(tmp_path / "m.inp", src)
    np.save(tmp_path / "run7.npy", src.positions)
    out = tmp_path / "d.h5"
    argv = ["import", "abaqus", "--inp", str(inp), "--frames", str(tmp_path / "run7.npy"),
            "--out", str(out), "--dt", "0.2", "--quiet", "--units", "mm"]
    assert main(argv) == 0
    assert open_dataset(out).names == ["run7"]
    assert main(["info", str(out)]) == 0
    assert "run7" in capsys.readouterr().out


def _shift_vessel(sim):
    pos = sim.positions.copy()
    pos[2, 6] += 0.1
    return dataclasses.replace(sim, positions=pos)


def test_bad_mesh_series(tmp_path, capsys):
    src = make_simulation("r", n_frames=4)
    ragged = write_series(tmp_path / "ragged", src)
    short = meshio.Mesh(src.positions[2, :12], [("tetra", [[0, 1, 2, 3]])])
    meshio.write(ragged / "frame_2.vtu", short)
    with pytest.raises(DatasetError, match=r"frame_2.vtu: simulation 'ragged': field "
                       r"'positions': 12 nodes, but the first frame has 13"):
        read_mesh_series(ragged)
    bad_type = dataclasses.replace(src, node_type=np.where(src.node_type == 0, 5, 1))
    folder = write_series(tmp_path / "badtype", bad_type, node_type_name="node_type")
    with pytest.raises(DatasetError, match="'badtype': field 'node_type': unknown node-type val"):
        read_mesh_series(folder)
    folder = write_series(tmp_path / "moves", _shift_vessel(src))
    with pytest.raises(DatasetError, match="'moves': field 'positions': vessel node 6 moves"):
        read_mesh_series(folder)
    nocells = write_series(tmp_path / "nocells", src, cells=False)
    with pytest.raises(DatasetError, match="'nocells': field 'node_type': no point-data"):
        read_mesh_series(nocells)
    orphan = tmp_path / "orphan"
    orphan.mkdir()
    meshio.write(orphan / "f0.vtu", meshio.Mesh(src.positions[0], [("tetra", src.clot_cells)]))
    with pytest.raises(DatasetError, match="8 nodes .* are in no tetra or triangle"):
        read_mesh_series(orphan)
    (tmp_path / "corrupt").mkdir()
    (tmp_path / "corrupt" / "f0.vtu").write_text("<VTKFile garbage")
    with pytest.raises(DatasetError, match="f0.vtu: simulation 'corrupt': field 'mesh'"):
        read_mesh_series(tmp_path / "corrupt")
    out = tmp_path / "x.h5"
    for source in (ragged, ragged / "frame_0.vtu", tmp_path / "missing"):
        assert main(["import", "vtu", str(source), "--out", str(out), "--quiet",
                     "--units", "mm"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("thrombojax import: error: ") and err.count("\n") == 1
        assert "Traceback" not in err and not out.exists()


def test_bad_abaqus_frames(tmp_path):
    src = make_simulation("a", n_frames=3)
    inp = write_inp(tmp_path / "m.inp", src)
    folder = tmp_path / "frames"
    folder.mkdir()
    np.save(folder / "frame_0.npy", src.positions[0])
    np.save(folder / "frame_1.npy", src.positions[1, :10])
    with pytest.raises(DatasetError, match=r"frame_1.npy: simulation 'x': field 'positions': "
                       "10 nodes, but the mesh has 13"):
        read_frames(folder, n_nodes=13, name="x")
    nan = src.positions.copy()
    nan[1, 3, 2] = np.nan
    np.save(tmp_path / "nan.npy", nan)
    with pytest.raises(DatasetError, match="'nan': field 'positions': non-finite value nan"):
        read_abaqus(inp, tmp_path / "nan.npy")
    np.save(tmp_path / "rank.npy", src.positions[0])
    with pytest.raises(DatasetError, match=r"'rank': field 'positions': shape \(13, 3\)"):
        read_abaqus(inp, tmp_path / "rank.npy")
    (tmp_path / "lab").mkdir()
    rows = np.column_stack([LABELS + 1, src.positions[0]])
    np.savetxt(tmp_path / "lab" / "f0.csv", rows, delimiter=",")
    with pytest.raises(DatasetError, match="node labels do not match"):
        read_abaqus(inp, tmp_path / "lab")
    two = tmp_path / "two.inp"
    two.write_text(inp.read_text() + "*Node\n999, 0, 0, 0\n")
    with pytest.raises(DatasetError, match="2 \\*Node blocks"):
        read_abaqus(two, tmp_path / "nan.npy")
    with pytest.raises(ConfigError, match="2 .inp files for 3 frame sources"):
        import_abaqus([inp, inp], [folder] * 3, tmp_path / "d.h5", progress=False)
