"""The outlet features: where the clot is against the vessel's open ends, ahead of its motion."""

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from thrombojax.errors import ConfigError
from thrombojax.graph.vessel_axis import outlet_features
from thrombojax.types import NodeType

ROT = Rotation.from_euler("xyz", [0.4, 2.1, -1.3]).as_matrix().astype(np.float32)


def _open_tube(clot_at: float, rng, length=12.0, n_wall=1500, n_clot=40):
    """A unit-radius straight tube along x from 0 to ``length`` (open at both ends), and a
    clot of half-length 0.5 around ``x = clot_at`` on its axis."""
    s = rng.uniform(0.0, length, n_wall)
    th = rng.uniform(0, 2 * np.pi, n_wall)
    wall = np.stack([s, np.cos(th), np.sin(th)], axis=1)
    clot = np.stack([rng.uniform(-0.5, 0.5, n_clot) + clot_at,
                     rng.uniform(-0.4, 0.4, n_clot), rng.uniform(-0.4, 0.4, n_clot)], axis=1)
    x = np.concatenate([wall, clot]).astype(np.float32)
    nt = np.array([NodeType.VESSEL] * n_wall + [NodeType.CLOT] * n_clot, np.int32)
    return x, nt


def _features(x_prev, x_cur, nt, radius=2.0, mask=None):
    mask = np.ones(len(nt), bool) if mask is None else mask
    return np.asarray(outlet_features(jnp.asarray(x_prev), jnp.asarray(x_cur), jnp.asarray(nt),
                                      jnp.asarray(mask), radius=radius))


def _moving(x, nt, velocity):
    """``(x_prev, x_cur)``: the clot moved by ``velocity`` into ``x``, the vessel still."""
    prev = x.copy()
    prev[nt == NodeType.CLOT] -= np.asarray(velocity, np.float32)
    return prev, x


def test_the_features_see_the_outlet_coming_and_nothing_inside_the_tube():
    """Mid-tube the vessel lies evenly around the clot (about 0); nearing the outlet at
    x = 12 the vessel lies behind the clot (negative, growing towards the end); leaving the
    inlet it lies ahead (positive); a clot at rest or with no vessel reads 0."""
    rng = np.random.default_rng(0)
    clot_means = {}
    for at in (6.0, 9.0, 10.5, 11.5, 1.0):
        x, nt = _open_tube(at, rng)
        f = _features(*_moving(x, nt, [0.3, 0.0, 0.0]), nt)
        clot = nt == NodeType.CLOT
        assert not f[~clot].any()
        assert np.allclose(f[clot, 1], f[clot, 0].mean(), atol=1e-6)
        clot_means[at] = f[clot, 1][0]
    assert abs(clot_means[6.0]) < 0.02
    assert clot_means[9.0] < clot_means[6.0] - 0.01
    assert clot_means[11.5] < clot_means[10.5] < clot_means[9.0] < 0
    assert clot_means[1.0] > 0.1
    x, nt = _open_tube(11.5, rng)
    # moving back into the tube the outlet lies behind the motion: the sign turns
    assert _features(*_moving(x, nt, [-0.3, 0.0, 0.0]), nt)[nt == NodeType.CLOT, 1][0] > 0.1
    assert not _features(x, x, nt).any()  # at rest
    clot_only = nt == NodeType.CLOT
    assert not _features(*_moving(x, nt, [0.3, 0, 0]), nt,
                         mask=clot_only).any()  # no real vessel node


def test_the_features_are_invariant_to_rotations_and_translations():
    rng = np.random.default_rng(1)
    x, nt = _open_tube(10.5, rng)
    prev, cur = _moving(x, nt, [0.25, 0.05, 0.0])
    base = _features(prev, cur, nt)
    shift = np.array([3.0, -7.0, 2.0], np.float32)
    moved = _features(prev @ ROT.T + shift, cur @ ROT.T + shift, nt)
    np.testing.assert_allclose(moved, base, atol=2e-5)
    with pytest.raises(ValueError, match="radius"):
        _features(prev, cur, nt, radius=0.0)


def test_outlet_features_reach_the_model_and_the_training_config():
    """A step with ``outlet_radius`` reads 2 more inputs per node, these features; a negative
    width is refused by the step and by the training options; they need the dense search."""
    from dataset_factory import check_step_input_option

    from thrombojax.graph.wall_nodes import DENSE_PLANE_NODES
    from thrombojax.train.checks import check_dense_inputs
    from thrombojax.train.config import TrainConfig

    rng = np.random.default_rng(2)
    x, nt = _open_tube(10.5, rng, n_wall=300, n_clot=20)
    x = x / 12.0
    prev, cur = _moving(x, nt, [0.02, 0.0, 0.0])
    mask = np.ones(len(nt), bool)
    extra = check_step_input_option(prev, cur, nt, mask, "outlet_radius", 2.0 / 12.0, 2,
                                    _features(prev, cur, nt, radius=2.0 / 12.0),
                                    "outlet_features", atol=1e-6)
    assert extra[nt == NodeType.CLOT, 1].min() < -0.01
    with pytest.raises(ConfigError, match="--outlet-features"):
        check_dense_inputs(TrainConfig(outlet_features=2.0), DENSE_PLANE_NODES + 64)
