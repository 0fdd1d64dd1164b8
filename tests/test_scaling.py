"""Isotropic scaling to [-1, 1]: bounds, one factor, exact inverse, pytree / jit, serialisation."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import make_simulation, write_good

from thrombojax.data.scaling import Scaling, fit_scaling
from thrombojax.errors import ConfigError, DatasetError
from thrombojax.io.hdf5 import open_dataset


def _trajectories():
    rng = np.random.default_rng(0)
    # far from the origin and anisotropic, so a per-axis or unshifted map would fail the checks
    return [
        (rng.standard_normal((4, 50, 3)) * [30.0, 2.0, 0.5] + [1e3, -250.0, 7.0]).astype(np.float32)
        for _ in range(3)
    ]


def test_all_within_unit_box_one_factor_and_exact_inverse():
    trajs = _trajectories()
    s = fit_scaling(trajs)
    assert np.shape(s.center) == (3,) and np.shape(s.scale) == ()
    stacked = np.concatenate([t.reshape(-1, 3) for t in trajs])
    for traj in trajs:
        y = s.apply(traj)
        assert y.dtype == np.float32 and np.abs(y).max() <= 1.0
        back = s.invert(y)
        np.testing.assert_allclose(back, traj, rtol=1e-6, atol=0)
    y_all = s.apply(stacked)
    # the widest axis spans [-1, 1] (up to the tiny safety margin); others are not stretched
    assert np.isclose(y_all[:, 0].max() - y_all[:, 0].min(), 2.0, rtol=1e-5)
    ratio = np.ptp(y_all, axis=0) / np.ptp(stacked.astype(np.float64), axis=0)
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-5)  # one factor for all axes
    v = stacked[1:] - stacked[:-1]
    np.testing.assert_allclose(s.apply_vector(v), y_all[1:] - y_all[:-1], atol=1e-6)
    np.testing.assert_allclose(s.invert_vector(s.apply_vector(v)), v, rtol=1e-5, atol=1e-4)


def test_fit_on_dataset_matches_arrays(tmp_path):
    ds = open_dataset(write_good(tmp_path / "d.h5", n_sims=3))
    from_ds = fit_scaling(ds)
    from_arrays = fit_scaling([ds.positions(n) for n in ds.names])
    assert from_ds.to_dict() == from_arrays.to_dict()
    only = fit_scaling(ds, names=["sim_1"])
    assert only.to_dict() == fit_scaling(ds.positions("sim_1")).to_dict()


def test_pytree_jit_and_round_trip_dict():
    s = fit_scaling(make_simulation().positions)
    x = jnp.asarray(make_simulation().positions[1])
    y = jax.jit(lambda sc, p: sc.apply(p))(s, x)
    np.testing.assert_allclose(np.asarray(y), s.apply(np.asarray(x)), atol=1e-6)
    back = jax.jit(lambda sc, q: sc.invert(q))(s, y)
    np.testing.assert_allclose(np.asarray(back), np.asarray(x), rtol=1e-6, atol=1e-6)
    assert len(jax.tree.leaves(s)) == 2
    d = s.to_dict()
    again = Scaling.from_dict(d)
    assert again.to_dict() == d
    np.testing.assert_array_equal(again.apply(np.asarray(x)), s.apply(np.asarray(x)))


def test_errors():
    with pytest.raises(DatasetError, match="zero extent"):
        fit_scaling(np.ones((2, 4, 3)))
    with pytest.raises(DatasetError, match="non-finite"):
        fit_scaling(np.full((2, 4, 3), np.nan))
    with pytest.raises(DatasetError, match="no positions"):
        fit_scaling([])
    with pytest.raises(DatasetError, match="shape"):
        fit_scaling([np.ones((4, 2))])
    with pytest.raises(ConfigError):
        Scaling.from_dict({"center": [0, 0], "scale": 1.0})
    with pytest.raises(ConfigError):
        Scaling.from_dict({"center": [0, 0, 0], "scale": 0.0})
    with pytest.raises(ConfigError):
        Scaling.from_dict({"scale": 1.0})


def test_vessel_radius_from_units_attribute_or_geometry(tmp_path):
    """r = 1 for data in vessel radii; else the clot-fills-the-lumen estimate (a tube of radius
    2.5 with a clot filling it gives ~2.5); an explicit attribute wins."""
    from thrombojax.data.radius import estimate_vessel_radius, vessel_radius
    from thrombojax.io.hdf5 import Simulation, open_dataset, write_dataset
    from thrombojax.types import NodeType

    ang = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    wall = np.concatenate([np.stack([np.full(40, x), 2.5 * np.cos(ang), 2.5 * np.sin(ang)], 1)
                           for x in np.linspace(-3, 3, 31)])
    clot = np.array([[x, 0.0, 0.0] for x in np.linspace(-1, 1, 5)])
    pos = np.concatenate([clot, wall]).astype(np.float32)
    nt = np.array([NodeType.CLOT] * 5 + [NodeType.VESSEL] * len(wall), np.int8)
    assert abs(estimate_vessel_radius(pos, nt) - 2.5) < 0.05
    sim = Simulation(name="tube", positions=np.repeat(pos[None], 3, 0), node_type=nt,
                     attrs={"dt": 0.1})
    mm = open_dataset(write_dataset(tmp_path / "mm.h5", [sim], name="mm", source="t", units="mm"))
    assert abs(vessel_radius(mm) - 2.5) < 0.05
    r = open_dataset(write_dataset(tmp_path / "r.h5", [sim], name="r", source="t"))
    assert vessel_radius(r) == 1.0  # the default unit is "vessel radius"
