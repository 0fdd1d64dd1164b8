"""Dataset schema: round trip, streaming atomic writes, lazy partial reads, bad-file corpus."""

from __future__ import annotations

import dataclasses
import pickle

import h5py
import numpy as np
import pytest
from dataset_factory import BAD_FILES, make_simulation, write_good

from thrombojax.errors import DatasetError
from thrombojax.io.hdf5 import FORMAT, DatasetWriter, open_dataset, write_dataset
from thrombojax.io.schema import VESSEL_TOLERANCE, validate_simulation


def test_round_trip_arrays_and_attributes(tmp_path):
    extra = {
        "rotation_deg": 30.0, "label": "bend", "flag": True, "count": 3,
        "axis": np.array([0.0, 0.0, 1.0]), "radii": [0.5, 1.5], "geometry": {"r": 1.0, "k": [1]},
        "note": None,
    }
    sims = [make_simulation(f"sim_{i}", seed=i, **extra) for i in (10, 2, 1)]
    path = write_dataset(tmp_path / "d.h5", sims, name="tiny", source="tests",
                         generator_config={"preset": "bendvessel-tiny", "n": np.int64(3),
                                           "r": np.array([0.5, 1.0])})
    ds = open_dataset(path)
    assert ds.names == ["sim_1", "sim_2", "sim_10"]  # natural order
    assert len(ds) == 3 and "sim_2" in ds and "sim_3" not in ds
    assert ds.attrs["format"] == FORMAT and ds.attrs["name"] == "tiny"
    assert ds.attrs["source"] == "tests" and ds.attrs["units"] == "vessel radius"
    assert ds.attrs["generator_config"] == {"preset": "bendvessel-tiny", "n": 3, "r": [0.5, 1.0]}
    again = pickle.loads(pickle.dumps(ds))  # no open handle: safe for worker processes
    np.testing.assert_array_equal(again.positions("sim_2"), ds.positions("sim_2"))
    for src in sims:
        got = ds[src.name]
        assert got.positions.dtype == np.float32 and got.node_type.dtype == np.int8
        assert got.clot_cells.dtype == np.int32 and got.wall_cells.dtype == np.int32
        for field in ("positions", "node_type", "clot_cells", "wall_cells"):
            np.testing.assert_array_equal(getattr(got, field), getattr(src, field))
        assert set(got.attrs) == set(src.attrs)
        for key, value in src.attrs.items():
            if isinstance(value, np.ndarray):
                np.testing.assert_array_equal(got.attrs[key], value)
            else:
                assert got.attrs[key] == value and type(got.attrs[key]) is type(value), key
        lazy = ds.sim_attrs(src.name)
        assert set(lazy) == set(src.attrs) and lazy["geometry"] == src.attrs["geometry"]
        assert ds.n_frames(src.name) == 5 and ds.n_nodes(src.name) == 13
        np.testing.assert_array_equal(ds.node_type(src.name), src.node_type)


def test_partial_reads(tmp_path):
    sim = make_simulation("a", n_frames=7)
    ds = open_dataset(write_dataset(tmp_path / "d.h5", [sim], name="t", source="tests"))
    pos = sim.positions
    np.testing.assert_array_equal(ds.positions("a"), pos)
    np.testing.assert_array_equal(ds.positions("a", 3), pos[3])
    np.testing.assert_array_equal(ds.positions("a", slice(2, 5)), pos[2:5])
    np.testing.assert_array_equal(ds.positions("a", slice(None, None, 3)), pos[::3])
    np.testing.assert_array_equal(ds.positions("a", np.array([5, 1, 5, 0])), pos[[5, 1, 5, 0]])
    np.testing.assert_array_equal(ds.positions("a", -1), pos[-1])
    with pytest.raises(IndexError, match="'a'.*positions.*7 frames"):
        ds.positions("a", 7)
    with pytest.raises(KeyError, match="no simulation 'b'"):
        ds["b"]


def test_streaming_writer_appears_only_on_clean_exit(tmp_path):
    target = tmp_path / "sub" / "d.h5"
    with DatasetWriter(target, name="t", source="tests") as writer:
        writer.add(make_simulation("s0"))
        assert not target.exists()
        writer.add(make_simulation("s1", seed=1))
        with pytest.raises(DatasetError, match="'s1'.*'name'.*duplicate"):
            writer.add(make_simulation("s1"))
    assert open_dataset(target).names == ["s0", "s1"]
    assert [p.name for p in target.parent.iterdir()] == ["d.h5"]  # no temporary left


def test_exception_mid_write_leaves_no_file(tmp_path):
    target = tmp_path / "d.h5"

    def sims():
        yield make_simulation("s0")
        raise RuntimeError("solver crashed")

    with pytest.raises(RuntimeError, match="solver crashed"):
        write_dataset(target, sims(), name="t", source="tests")
    assert list(tmp_path.iterdir()) == []
    # an invalid simulation mid-stream also aborts the whole write, and an old file survives
    write_good(target)
    before = target.read_bytes()
    bad = dataclasses.replace(make_simulation("s1"), node_type=np.zeros(13, np.int8))
    with pytest.raises(DatasetError, match="no clot nodes"):
        write_dataset(target, [make_simulation("s0"), bad], name="t", source="tests")
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["d.h5"]


def test_writer_refuses_empty_dataset_and_overwrite(tmp_path):
    with pytest.raises(DatasetError, match="no simulations"):
        write_dataset(tmp_path / "d.h5", [], name="t", source="tests")
    assert list(tmp_path.iterdir()) == []
    write_good(tmp_path / "d.h5")
    with pytest.raises(FileExistsError):
        write_dataset(tmp_path / "d.h5", [make_simulation()], name="t", source="t", overwrite=False)


def test_float64_positions_are_stored_as_float32(tmp_path):
    sim = make_simulation("s")
    sim64 = dataclasses.replace(sim, positions=sim.positions.astype(np.float64))
    got = open_dataset(write_dataset(tmp_path / "d.h5", [sim64], name="t", source="t"))["s"]
    assert got.positions.dtype == np.float32
    np.testing.assert_array_equal(got.positions, sim.positions)


def _bad(sim, **changes):
    return dataclasses.replace(sim, **changes)


def _moved_vessel(scale: float):
    sim = make_simulation("s")
    pos = sim.positions.copy()
    extent = float((pos.max(axis=(0, 1)) - pos.min(axis=(0, 1))).max())
    pos[2, 9, 2] += scale * VESSEL_TOLERANCE * extent
    return _bad(sim, positions=pos)


IN_MEMORY_BAD = {
    "nan": (lambda s: _bad(s, positions=np.where(np.arange(3) == 1, np.nan, s.positions)),
            "positions", "non-finite"),
    "inf": (lambda s: _bad(s, positions=np.where(np.arange(3) == 2, -np.inf, s.positions)),
            "positions",
            "non-finite"),
    "length": (lambda s: _bad(s, node_type=s.node_type[:-1]), "node_type", "length 12 != 13"),
    "unknown": (lambda s: _bad(s, node_type=s.node_type + 2), "node_type", "unknown node-type"),
    "no_clot": (lambda s: _bad(s, node_type=np.zeros(13, np.int8)), "node_type", "no clot"),
    "vessel_moves": (lambda s: _moved_vessel(10.0), "positions", "vessel node 9 moves"),
    "int_positions": (lambda s: _bad(s, positions=s.positions.astype(np.int32)), "positions",
                      "wrong dtype"),
    "float_node_type": (lambda s: _bad(s, node_type=s.node_type.astype(float)), "node_type",
                        "wrong dtype"),
    "rank": (lambda s: _bad(s, positions=s.positions[0]), "positions", "wrong shape"),
    "rank_node_type": (lambda s: _bad(s, node_type=s.node_type[None]), "node_type", "wrong rank"),
    "empty": (lambda s: _bad(s, positions=s.positions[:0]), "positions", "empty simulation"),
    "cells": (lambda s: _bad(s, wall_cells=s.wall_cells + 100), "wall_cells", "out of range"),
    "dt": (lambda s: _bad(s, attrs={"dt": -1.0}), "attrs/dt", "> 0"),
    "bad_name": (lambda s: _bad(s, name="a/b"), "name", "without '/'"),
}


@pytest.mark.parametrize("case", sorted(IN_MEMORY_BAD))
def test_validate_simulation_rejects(case):
    build, field, text = IN_MEMORY_BAD[case]
    sim = build(make_simulation("s"))
    with pytest.raises(DatasetError) as info:
        validate_simulation(sim, path="f.h5")
    msg = str(info.value)
    assert msg.startswith("f.h5: simulation ") and f"field '{field}'" in msg and text in msg
    assert "\n" not in msg


def test_vessel_tolerance_is_relative_to_the_bounding_box():
    validate_simulation(make_simulation("s"))
    validate_simulation(_moved_vessel(0.5))  # half the tolerance: accepted
    with pytest.raises(DatasetError, match="vessel node 9"):
        validate_simulation(_moved_vessel(2.0))
    big = _moved_vessel(0.5)  # the same relative drift at 1000x the size is still accepted
    validate_simulation(_bad(big, positions=big.positions * np.float32(1000.0)))


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_files_raise_named_one_line_errors(tmp_path, case):
    build, sim, field = BAD_FILES[case]
    path = build(tmp_path / f"{case}.h5")
    with pytest.raises(DatasetError) as info:
        ds = open_dataset(path)
        ds.validate()
    msg = str(info.value)
    assert msg.startswith(str(path)) and "\n" not in msg
    if case in ("unknown_node_type", "no_clot_nodes"):  # the lazy accessor checks values too
        with pytest.raises(DatasetError, match=f"simulation '{sim}': field 'node_type'"):
            open_dataset(path).node_type(sim)
    if sim is not None:
        assert f"simulation '{sim}'" in msg
    if field is not None:
        assert f"field '{field}'" in msg


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        open_dataset(tmp_path / "nope.h5")
    with pytest.raises(IsADirectoryError):
        open_dataset(tmp_path)


def test_simulation_group_without_simulations(tmp_path):
    path = tmp_path / "d.h5"
    write_good(path)
    with h5py.File(path, "r+") as h5:
        del h5["simulations/sim_0"], h5["simulations/sim_1"]
    with pytest.raises(DatasetError, match="field 'simulations': no simulations"):
        open_dataset(path)
