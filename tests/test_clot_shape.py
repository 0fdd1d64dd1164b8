"""The clot shape features: each clot node's place along the clot's motion, the clot's length
and width (:func:`thrombojax.graph.clot_shape.clot_shape_features`)."""

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from thrombojax.graph.clot_shape import CLOT_SHAPE_FEATURES, clot_shape_features
from thrombojax.models.registry import create_model, get_config
from thrombojax.simulator.step import make_step
from thrombojax.types import NodeType

ROT = Rotation.from_euler("xyz", [0.4, 2.1, -1.3]).as_matrix().astype(np.float32)


def _clot_and_ring(rng, n_clot=60):
    """A clot (a cloud 3 long along x, 1 across) beside a ring of 16 vessel nodes, 4 padded
    nodes last; returns ``(x, node_type, mask)``."""
    clot = rng.normal(size=(n_clot, 3)) * np.array([1.0, 0.35, 0.35])
    ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    ring = np.stack([np.zeros(16), 2 * np.cos(ang), 2 * np.sin(ang)], axis=1)
    x = np.concatenate([ring, clot, np.full((4, 3), 9.0)]).astype(np.float32)
    nt = np.array([NodeType.VESSEL] * 16 + [NodeType.CLOT] * n_clot + [NodeType.CLOT] * 4,
                  np.int32)
    mask = np.arange(len(x)) < 16 + n_clot
    return x, nt, mask


def _features(x_prev, x_cur, nt, mask, scale=0.5):
    return np.asarray(clot_shape_features(jnp.asarray(x_prev), jnp.asarray(x_cur),
                                          jnp.asarray(nt), jnp.asarray(mask), scale=scale))


def _moving(x, nt, mask, velocity):
    prev = x.copy()
    prev[(nt == NodeType.CLOT) & mask] -= np.asarray(velocity, np.float32)
    return prev, x


def test_the_features_are_each_node_s_place_along_the_motion_and_the_clot_s_size():
    rng = np.random.default_rng(0)
    x, nt, mask = _clot_and_ring(rng)
    clot = (nt == NodeType.CLOT) & mask
    f = _features(*_moving(x, nt, mask, [0.3, 0.0, 0.0]), nt, mask)
    assert f.shape == (len(x), CLOT_SHAPE_FEATURES)
    assert not f[~clot].any()  # vessel and padded nodes get zeros
    rel = x[clot] - x[clot].mean(axis=0)
    np.testing.assert_allclose(f[clot, 0], rel[:, 0] / 0.5, atol=1e-5)
    np.testing.assert_allclose(f[clot, 1], np.sqrt((rel[:, 0] ** 2).mean()) / 0.5, rtol=1e-5)
    np.testing.assert_allclose(f[clot, 2], np.sqrt((rel[:, 1:] ** 2).mean()) / 0.5, rtol=1e-5)
    # stretched along the motion by 1.3: the place and the length scale, the width stays
    stretched = x.copy()
    stretched[clot, 0] = x[clot, 0].mean() + 1.3 * rel[:, 0]
    g = _features(*_moving(stretched, nt, mask, [0.3, 0.0, 0.0]), nt, mask)
    np.testing.assert_allclose(g[clot, :2], 1.3 * f[clot, :2], rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(g[clot, 2], f[clot, 2], rtol=1e-5)
    # at rest: no direction, the size spread over all three axes
    rest = _features(x, x, nt, mask)
    assert not rest[clot, :2].any()
    np.testing.assert_allclose(rest[clot, 2], np.sqrt((rel ** 2).mean()) / 0.5, rtol=1e-5)
    with pytest.raises(ValueError, match="scale"):
        _features(x, x, nt, mask, scale=0.0)


def test_the_features_are_invariant_to_rotations_and_translations():
    rng = np.random.default_rng(1)
    x, nt, mask = _clot_and_ring(rng)
    prev, cur = _moving(x, nt, mask, [0.25, 0.05, -0.1])
    shift = np.array([3.0, -7.0, 2.0], np.float32)
    np.testing.assert_allclose(_features(prev @ ROT.T + shift, cur @ ROT.T + shift, nt, mask),
                               _features(prev, cur, nt, mask), atol=2e-5)


def test_shape_features_reach_the_model_and_the_training_config():
    """A step with ``shape_radius`` reads 3 more inputs per node, these features; a negative
    length is refused by the step and by the training options."""
    from dataset_factory import check_step_input_option

    x, nt, mask = _clot_and_ring(np.random.default_rng(2), n_clot=24)
    x = x / 10.0
    prev, cur = _moving(x, nt, mask, [0.02, 0.0, 0.0])
    check_step_input_option(prev, cur, nt, mask, "shape_radius", 0.1, CLOT_SHAPE_FEATURES,
                            _features(prev, cur, nt, mask, scale=0.1), "shape_features",
                            atol=1e-5)


def _stretch_carry_after_training(shape_radius: float) -> float:
    """The tiny step (with the shape features when ``shape_radius > 0``) trained with stretch
    noise 0.3 on clots that are random clouds of nodes
    (:func:`dataset_factory.stretch_carry_after_training` on
    :func:`dataset_factory.ring_clot_window`, 400 Adam steps): the share of a 5 % stretch it
    keeps."""
    from dataset_factory import ring_clot_window, stretch_carry_after_training
    from test_speed_noise import STATS

    step = make_step(create_model("mgn", get_config("mgn", tiny=True, max_neighbors=8,
                                                    radius=0.45)), shape_radius=shape_radius)
    return stretch_carry_after_training(step, ring_clot_window, STATS, stretch_noise=0.3,
                                        steps=400)


def test_shape_features_let_a_model_see_and_take_back_a_stretch():
    """Fails without the features: on a random cloud of nodes (no regular edges to read a
    stretch from), the tiny model trained with stretch noise keeps a stretch it is given (0.98
    when written); with the clot's length and each node's place as inputs it takes back about
    half of it (0.53 after 400 steps)."""
    assert _stretch_carry_after_training(0.0) > 0.9
    assert _stretch_carry_after_training(0.3) < 0.75
