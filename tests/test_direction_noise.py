"""Direction noise: the clot's input motion turned by one random rotation, s_t and the target
unchanged.

A rollout's clot drifts off the true track, and a step trained on clean windows keeps moving a
clot the way it came in (constant velocity's behaviour), so the drift is never pulled back. The
direction noise (:func:`thrombojax.train.noise.add_direction_noise`) shows it clots that come in
across their path with the true next frame as the target, so it learns to follow the vessel
rather than its input's direction (:func:`thrombojax.eval.drift.direction_carry` measures the
share of a sideways turn a step keeps).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import tiny_mgn_step, train_tiny_step
from test_speed_noise import STATS, _batch, _window

from thrombojax.errors import ConfigError
from thrombojax.eval.drift import direction_carry
from thrombojax.train.config import TrainConfig
from thrombojax.train.noise import add_direction_noise, rotation_matrix
from thrombojax.types import NodeType


def test_rotation_matrix_turns_about_its_axis_and_is_the_identity_at_zero():
    quarter = np.asarray(rotation_matrix(jnp.array([0.0, 0.0, np.pi / 2])))
    np.testing.assert_allclose(quarter @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-6)
    w = jnp.array([0.3, -0.2, 0.5])
    r = np.asarray(rotation_matrix(w))
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-6)
    np.testing.assert_allclose(r @ np.asarray(w), np.asarray(w), atol=1e-6)  # the axis stays
    np.testing.assert_allclose(rotation_matrix(jnp.zeros(3)), np.eye(3))
    assert np.isfinite(np.asarray(jax.grad(lambda v: rotation_matrix(v).sum())(jnp.zeros(3)))).all()


def test_direction_noise_turns_the_input_motion_of_the_clot_by_one_rotation():
    frames, nt, mask = _window(0.05, frames=6)
    out = np.asarray(add_direction_noise(jax.random.key(0), frames, nt, mask, std=0.2,
                                         current=3))
    f = np.asarray(frames)
    clot = np.asarray((nt == NodeType.CLOT) & mask)
    motion = (f[3] - f[:3])[:, clot].reshape(-1, 3)
    noisy = (out[3] - out[:3])[:, clot].reshape(-1, 3)
    np.testing.assert_allclose(np.linalg.norm(noisy, axis=1), np.linalg.norm(motion, axis=1),
                               rtol=1e-4, atol=1e-7)  # turned, not stretched
    rot, *_ = np.linalg.lstsq(motion, noisy, rcond=None)  # one linear map for every node, frame
    np.testing.assert_allclose(motion @ rot, noisy, atol=2e-6)
    cos = (noisy * motion).sum(1) / np.linalg.norm(motion, axis=1) ** 2
    assert cos.max() < 1.0 - 1e-4  # it did turn
    assert not (out - f)[:, ~clot].any()  # vessel and padded nodes stay
    assert not (out - f)[3:].any()  # s_t and the targets stay


def test_direction_noise_off_and_bad_values():
    frames, nt, mask = _window(0.05)
    assert add_direction_noise(jax.random.key(0), frames, nt, mask, std=0.0, current=1) is frames
    with pytest.raises(ValueError, match="direction noise std"):
        add_direction_noise(jax.random.key(0), frames, nt, mask, std=-0.1, current=1)
    with pytest.raises(ValueError, match="index >= 1"):
        add_direction_noise(jax.random.key(0), frames, nt, mask, std=0.1, current=0)
    with pytest.raises(ConfigError, match="direction_noise"):
        TrainConfig(direction_noise=-0.1)
    TrainConfig(direction_noise=0.1)
    from thrombojax.cli import build_parser

    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--direction-noise", "0.1"])
    assert args.direction_noise == 0.1


def test_the_training_loss_uses_the_direction_noise():
    from thrombojax.train.step import batch_loss

    batch, step = _batch(), tiny_mgn_step()
    params = step.init(jax.random.key(0), batch.frames[0, 0], batch.frames[0, 1],
                       batch.node_type[0], batch.mask[0])
    losses = [float(batch_loss(step, params, STATS, batch, jax.random.key(1), train=True,
                               direction_noise=s)[0]) for s in (0.0, 0.0, 0.2)]
    assert losses[0] == losses[1] != losses[2]


def _carry_after_training(direction_noise: float) -> float:
    """Train the tiny step on clots sliding along x, then return the share of a 0.1 rad
    sideways turn of its input motion that its prediction keeps."""
    step = tiny_mgn_step()
    params = train_tiny_step(step, _batch(), STATS, direction_noise=direction_noise)
    frames, nt, mask = _window(0.05, seed=7)
    return float(direction_carry(step, params, STATS, np.asarray(frames), np.asarray(nt),
                                 [1, 2], angle=0.1, mask=np.asarray(mask)).mean())


def test_direction_noise_teaches_a_model_to_follow_the_path_not_its_input_direction():
    """Fails without the noise: trained on clots that slide along x, the model keeps a sideways
    turn of its input motion (as constant velocity does, carry near 1); with the noise (0.5 rad
    per axis) it keeps less than half as much."""
    without = _carry_after_training(0.0)
    assert without > 0.7
    assert _carry_after_training(0.5) < 0.5 * without


def test_direction_carry_of_constant_velocity_is_one_and_bad_values_are_refused():
    from thrombojax.models.registry import create_model, identity_stats
    from thrombojax.simulator.step import make_step

    frames, nt, mask = (np.asarray(a) for a in _window(0.05, frames=5))
    cv = make_step(create_model("constant_velocity"))
    np.testing.assert_allclose(direction_carry(cv, {}, identity_stats(), frames, nt, [1, 2, 3],
                                               angle=0.1, mask=mask), 1.0, rtol=1e-3)
    for bad in (0.0, 2.0):
        with pytest.raises(ConfigError, match="angle"):
            direction_carry(cv, {}, identity_stats(), frames, nt, [1], angle=bad)
    still = np.repeat(frames[:1], 3, axis=0)
    with pytest.raises(ConfigError, match="does not move at frame 1"):
        direction_carry(cv, {}, identity_stats(), still, nt, [1], angle=0.1, mask=mask)
