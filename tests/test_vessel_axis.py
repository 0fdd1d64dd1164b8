"""The vessel-axis features: the local axis of the vessel and the velocity split along it."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from thrombojax.errors import ConfigError
from thrombojax.graph.vessel_axis import axis_velocity_features, vessel_axis
from thrombojax.io.hdf5 import open_dataset
from thrombojax.models.registry import create_model, get_config, identity_stats
from thrombojax.simulator.step import make_step
from thrombojax.types import NodeType

ROT = Rotation.from_euler("xyz", [0.4, 2.1, -1.3]).as_matrix()


def _tube(centre, tangent, rng, n_wall=900, n_clot=60, half_length=5.0):
    """Wall nodes of a unit-radius tube around ``centre(s)`` and clot nodes near its axis."""
    s = rng.uniform(-half_length, half_length, n_wall)
    th = rng.uniform(0, 2 * np.pi, n_wall)
    pts = []
    for si, ti in zip(s, th, strict=True):
        t = tangent(si)
        e1 = np.cross(t, [0.0, 0.0, 1.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(t, e1)
        pts.append(centre(si) + np.cos(ti) * e1 + np.sin(ti) * e2)
    sc = rng.uniform(-1.0, 1.0, n_clot)
    clot = np.array([centre(si) for si in sc]) + rng.normal(0, 0.2, (n_clot, 3))
    x = np.concatenate([np.array(pts), clot]).astype(np.float32)
    nt = np.array([NodeType.VESSEL] * n_wall + [NodeType.CLOT] * n_clot, np.int32)
    return x, nt, sc


def _axis(x, nt, radius=2.0):
    return np.asarray(vessel_axis(jnp.asarray(x), jnp.asarray(nt), jnp.ones(len(nt), bool),
                                  radius=radius))


def test_the_axis_of_a_straight_tube_is_its_axis_and_turns_with_it():
    rng = np.random.default_rng(0)
    d = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    x, nt, _ = _tube(lambda s: s * d, lambda s: d, rng)
    clot = nt == NodeType.CLOT
    t = _axis(x, nt)
    assert np.allclose(np.linalg.norm(t[clot], axis=1), 1.0, atol=1e-4)
    assert np.abs(t[clot] @ d).min() > 0.999
    t_rot = _axis(x @ ROT.T.astype(np.float32), nt)
    assert np.abs(np.sum(t_rot[clot] * (t[clot] @ ROT.T), axis=1)).min() > 0.999


def test_the_axis_follows_a_bend():
    """In a tube bent on a circle of radius 4 the axis at each clot node is the bend's tangent
    there, not a mean direction of the vessel."""
    rng = np.random.default_rng(1)
    big = 4.0

    def centre(s):
        return big * np.array([np.sin(s / big), 1.0 - np.cos(s / big), 0.0])

    def tangent(s):
        return np.array([np.cos(s / big), np.sin(s / big), 0.0])

    x, nt, s = _tube(centre, tangent, rng, n_wall=1500, half_length=6.0)
    clot = nt == NodeType.CLOT
    t = _axis(x, nt)[clot]
    want = np.array([tangent(si) for si in s])
    assert np.abs(np.sum(t * want, axis=1)).min() > 0.97
    assert np.abs(t @ tangent(0.0)).min() < 0.99  # it turns along the clot (chord ~ 0.5 rad)


def test_the_velocity_split_adds_up_rotates_with_the_input_and_spares_the_vessel():
    rng = np.random.default_rng(2)
    d = np.array([0.0, 0.6, 0.8])
    x, nt, _ = _tube(lambda s: s * d, lambda s: d, rng)
    clot = nt == NodeType.CLOT
    v = rng.normal(0, 0.05, x.shape).astype(np.float32)
    mask = jnp.ones(len(nt), bool)
    f = np.asarray(axis_velocity_features(jnp.asarray(x - v), jnp.asarray(x), jnp.asarray(nt),
                                          mask, radius=2.0, velocity_scale=0.5))
    assert f.shape == (len(nt), 6)
    np.testing.assert_allclose(f[clot, :3] + f[clot, 3:], v[clot] / 0.5, atol=1e-5)
    assert np.abs(np.cross(f[clot, :3], d)).max() < 5e-3  # along: parallel to the axis (|v| ~ 0.2)
    assert np.abs(f[clot, 3:] @ d).max() < 5e-3  # across: orthogonal to it
    assert not f[~clot].any()
    r = ROT.astype(np.float32)
    f_rot = np.asarray(axis_velocity_features(jnp.asarray((x - v) @ r.T), jnp.asarray(x @ r.T),
                                              jnp.asarray(nt), mask, radius=2.0,
                                              velocity_scale=0.5))
    np.testing.assert_allclose(f_rot[clot, :3], f[clot, :3] @ r.T, atol=1e-4)
    np.testing.assert_allclose(f_rot[clot, 3:], f[clot, 3:] @ r.T, atol=1e-4)


def test_no_vessel_means_no_axis_and_a_bad_width_is_refused():
    x = np.random.default_rng(3).normal(size=(20, 3)).astype(np.float32)
    nt = np.full(20, NodeType.CLOT, np.int32)
    assert not _axis(x, nt).any()
    with pytest.raises(ValueError, match="radius"):
        _axis(x, nt, radius=0.0)


def test_axis_features_reach_the_model(tmp_path):
    """The step with ``axis_radius`` reads 6 more inputs per node, which are the split of the
    clot's velocity; a negative width is refused."""
    from thrombojax.sim.generate import generate_dataset

    path = generate_dataset("clotentry-tiny", tmp_path / "ce.h5", n_sims=1, seed=3,
                            progress=False)
    ds = open_dataset(path)
    pos = np.asarray(ds.positions(ds.names[0]), np.float32)
    nt = np.asarray(ds.node_type(ds.names[0]))
    pos = pos[3:5] / np.abs(pos).max()
    mask = np.ones(len(nt), bool)
    model = create_model("mgn", get_config("mgn", tiny=True, max_neighbors=4))
    plain, axial = make_step(model), make_step(model, axis_radius=0.3)
    k0 = plain.init(jax.random.key(0), pos[0], pos[1], nt, mask)["params"]
    k1 = axial.init(jax.random.key(0), pos[0], pos[1], nt, mask)["params"]
    assert (k1["node_encoder"]["dense_0"]["kernel"].shape[0]
            == k0["node_encoder"]["dense_0"]["kernel"].shape[0] + 6)
    extra = np.asarray(axial.inputs(identity_stats(), pos[0], pos[1], nt, mask).extra)
    clot = nt == NodeType.CLOT
    np.testing.assert_allclose(extra[clot, :3] + extra[clot, 3:], (pos[1] - pos[0])[clot],
                               atol=1e-6)
    assert np.abs(extra[clot, :3]).max() > 0
    with pytest.raises(ConfigError, match="axis_radius"):
        make_step(model, axis_radius=-1.0)


def test_cli_refuses_a_negative_axis_width_before_training(tmp_path, capsys):
    """A negative `--axis-features` is refused before training, naming the option (that the
    option reaches the run and the reloaded step: tests/test_step_options_cli.py)."""
    from dataset_factory import tiny_cli_dataset

    from thrombojax.cli import main

    data = tiny_cli_dataset(tmp_path, n_nodes=80)
    with pytest.raises(SystemExit):
        main(["train", "--dataset", str(data), "--model", "mgn", "--out", str(tmp_path / "bad"),
              "--tiny", "--epochs", "1", "--axis-features", "-1", "--quiet"])
    assert "--axis-features" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_samples_too_large_for_the_dense_wall_search_are_refused_before_training():
    from thrombojax.graph.wall_nodes import DENSE_PLANE_NODES
    from thrombojax.train.checks import check_dense_inputs
    from thrombojax.train.config import TrainConfig

    with pytest.raises(ConfigError, match="--axis-features.*--nodes-per-sample"):
        check_dense_inputs(TrainConfig(axis_features=2.0), DENSE_PLANE_NODES + 64, "d.h5")
    with pytest.raises(ConfigError, match="--wall-signed"):
        check_dense_inputs(TrainConfig(wall_features=0.5, wall_signed=True), 27008)
    check_dense_inputs(TrainConfig(axis_features=2.0), DENSE_PLANE_NODES)
    check_dense_inputs(TrainConfig(), 27008)  # no dense input: any size
