"""The vessel radius every evaluation report divides lengths by (thrombojax/data/radius.py)."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from thrombojax.data.radius import estimate_vessel_radius, vessel_radius, vessel_radius_and_source
from thrombojax.errors import DatasetError
from thrombojax.io.hdf5 import Simulation, open_dataset, write_dataset
from thrombojax.types import NodeType


def _tube(radius: float, *, bend: bool = False, length: float = 12.0, rings: int = 40,
          around: int = 16, clot_outside: bool = False, seed: int = 0):
    """Wall rings of a tube of ``radius`` around a straight (or quarter-circle) centreline, and
    a clot cloud (inside the lumen at its start, or before the inlet): ([N, 3], [N])."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, length, rings)
    ang = np.linspace(0, 2 * np.pi, around, endpoint=False)
    if bend:  # quarter circle of centreline radius 4 radii in the x-y plane
        big = 4.0 * radius
        phi = s / length * np.pi / 2
        centre = np.stack([big * np.sin(phi), big * (1 - np.cos(phi)), 0 * phi], 1)
        tangent = np.stack([np.cos(phi), np.sin(phi), 0 * phi], 1)
    else:
        centre = np.stack([s, 0 * s, 0 * s], 1)
        tangent = np.tile([1.0, 0, 0], (rings, 1))
    n1 = np.cross(tangent, [0.0, 0.0, 1.0])
    n1 /= np.linalg.norm(n1, axis=1, keepdims=True)
    n2 = np.cross(tangent, n1)
    wall = (centre[:, None] + radius * (np.cos(ang)[None, :, None] * n1[:, None]
                                        + np.sin(ang)[None, :, None] * n2[:, None])).reshape(-1, 3)
    clot = rng.uniform(-0.7, 0.7, (60, 3)) * radius
    clot[:, 0] = rng.uniform(0.1, 2.0, 60) * radius - (3.0 * radius if clot_outside else 0.0)
    pts = np.concatenate([clot, wall])
    node_type = np.r_[np.full(60, NodeType.CLOT), np.full(len(wall), NodeType.VESSEL)]
    return pts, node_type.astype(np.int8)


@pytest.mark.parametrize("radius", [0.37, 1.0, 2.5])
@pytest.mark.parametrize("bend", [False, True])
def test_estimate_on_tubes_of_known_radius(radius, bend):
    pts, node_type = _tube(radius, bend=bend, length=12.0 * radius)
    assert estimate_vessel_radius(pts, node_type) == pytest.approx(radius, rel=0.03)
    # the clot's position does not matter: it may start before the inlet
    pts, node_type = _tube(radius, bend=bend, length=12.0 * radius, clot_outside=True)
    assert estimate_vessel_radius(pts, node_type) == pytest.approx(radius, rel=0.03)


def test_estimate_is_shift_invariant_and_needs_a_wall():
    pts, node_type = _tube(1.3)
    a = estimate_vessel_radius(pts, node_type)
    assert estimate_vessel_radius(pts + [100.0, -50.0, 7.0], node_type) == pytest.approx(a)
    with pytest.raises(DatasetError, match="vessel nodes"):
        estimate_vessel_radius(pts[:65], node_type[:65])


def _write(path, radius, *, units):
    sims = []
    for i in range(2):
        pts, node_type = _tube(radius, seed=i)
        sims.append(Simulation(name=f"s{i}", positions=np.stack([pts, pts]).astype(np.float32),
                               node_type=node_type, attrs={"dt": 1.0}))
    return write_dataset(path, sims, name="tube", source="test", units=units)


def test_dataset_radius_sources(tmp_path):
    # no usable unit: estimated from the geometry (median over simulations)
    path = _write(tmp_path / "mm.h5", 1.6, units="mm")
    r, source = vessel_radius_and_source(open_dataset(path))
    assert r == pytest.approx(1.6, rel=0.03) and "estimated" in source and "2 simulation" in source
    # the file attribute wins over everything
    with h5py.File(path, "r+") as h5:
        h5.attrs["vessel_radius"] = 1.75
    assert vessel_radius_and_source(open_dataset(path)) == (1.75, "file attribute vessel_radius")
    # the built-in solver's unit: exactly 1, whatever the geometry
    path = _write(tmp_path / "r.h5", 1.6, units="vessel radius")
    assert vessel_radius(open_dataset(path)) == 1.0


@pytest.mark.parametrize("bad", [-1.0, 0.0, "wide", float("nan")])
def test_bad_radius_attribute_is_one_line_error(tmp_path, bad):
    path = _write(tmp_path / "bad.h5", 1.0, units="mm")
    with h5py.File(path, "r+") as h5:
        h5.attrs["vessel_radius"] = bad
    with pytest.raises(DatasetError, match=r"bad\.h5: field 'vessel_radius'") as err:
        vessel_radius(open_dataset(path))
    assert "\n" not in str(err.value)


def test_estimate_on_solver_data_is_one_radius(tmp_path):
    """The built-in solver writes vessel radii: the geometric estimate must agree (~1)."""
    from thrombojax.sim.generate import generate_dataset

    path = tmp_path / "bend.h5"
    generate_dataset("bendvessel-tiny", path, n_sims=2, seed=1, progress=False)
    ds = open_dataset(path)
    for name in ds.names:
        r = estimate_vessel_radius(ds.positions(name, 0), ds.node_type(name))
        assert r == pytest.approx(1.0, abs=0.03), name
