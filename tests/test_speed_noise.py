"""Speed noise: the clot's input motion scaled by one random factor, s_t and the target unchanged.

The true clot slides at a steady speed that no input shows but its own motion, so a step trained
on clean windows keeps whatever speed it is given (constant velocity's behaviour): in a rollout
its own speed error is never pulled back. The speed noise
(:func:`thrombojax.train.noise.add_speed_noise`) shows it clots that move too fast or too slow
with the true next frame as the target, so it learns to bring the speed back
(:func:`thrombojax.eval.drift.speed_carry` measures how much of a speed error a step keeps).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import ring_clot_window, tiny_mgn_step, train_tiny_step, window_batch

from thrombojax.errors import ConfigError
from thrombojax.eval.drift import speed_carry
from thrombojax.train.config import TrainConfig
from thrombojax.train.noise import add_speed_noise
from thrombojax.types import NodeType, TargetStats

STATS = TargetStats(mean=jnp.zeros(3), std=jnp.full(3, 0.02), velocity_std=jnp.asarray(0.05))


def _window(speed: float, frames: int = 4, seed: int = 0):
    """A clot moving along x at ``speed`` per frame, slightly sheared, beside a ring of vessel
    nodes (:func:`dataset_factory.ring_clot_window`)."""
    return ring_clot_window(speed, shear=0.01, frames=frames, seed=seed)


def test_speed_noise_scales_the_input_motion_of_the_clot_by_one_factor():
    frames, nt, mask = _window(0.05, frames=6)
    out = np.asarray(add_speed_noise(jax.random.key(0), frames, nt, mask, std=0.2, current=3))
    f = np.asarray(frames)
    clot = np.asarray((nt == NodeType.CLOT) & mask)
    motion, noisy = (f[3] - f[:3])[:, clot], (out[3] - out[:3])[:, clot]
    factor = noisy[0, 0, 0] / motion[0, 0, 0]  # along x: 0.15 in three frames
    assert abs(factor - 1.0) > 1e-3
    np.testing.assert_allclose(noisy, factor * motion, atol=2e-6)  # one factor, every node, frame
    assert not (out - f)[:, ~clot].any()  # vessel and padded nodes stay
    assert not (out - f)[3:].any()  # s_t and the targets stay


def test_speed_noise_off_and_bad_values():
    frames, nt, mask = _window(0.05)
    assert add_speed_noise(jax.random.key(0), frames, nt, mask, std=0.0, current=1) is frames
    with pytest.raises(ValueError, match="speed noise std"):
        add_speed_noise(jax.random.key(0), frames, nt, mask, std=-0.1, current=1)
    with pytest.raises(ValueError, match="index >= 1"):
        add_speed_noise(jax.random.key(0), frames, nt, mask, std=0.1, current=0)
    with pytest.raises(ConfigError, match="speed_noise"):
        TrainConfig(speed_noise=-0.1)
    TrainConfig(speed_noise=0.03)
    from thrombojax.cli import build_parser

    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--speed-noise", "0.03"])
    assert args.speed_noise == 0.03


def test_speed_noise_on_steady_windows_only_leaves_a_clot_that_speeds_up_or_rests():
    """``steady = 0.1``: a clot keeping its speed to s_t+1 is noised as before (the same draw);
    one that speeds up by 13 % to s_t+1, or rests, keeps its true motion. Fails if the fraction
    is ignored (every window noised) or turns the noise off everywhere."""
    key = jax.random.key(0)
    for speed, accel, shear, noised in ((0.05, 0.0, 0.01, True), (0.05, 0.01, 0.01, False),
                                        (0.0, 0.0, 0.0, False)):
        frames, nt, mask = ring_clot_window(speed, accel, shear=shear, frames=5)
        out = add_speed_noise(key, frames, nt, mask, std=0.2, current=3, steady=0.1)
        assert bool(jnp.any(out != frames)) == noised, (speed, accel, shear)
        if noised:
            np.testing.assert_array_equal(
                out, add_speed_noise(key, frames, nt, mask, std=0.2, current=3))
    # the window's last frame is s_t: no s_t+1 to compare with
    with pytest.raises(ValueError, match="s_t\\+1"):
        add_speed_noise(key, frames[:4], nt, mask, std=0.2, current=3, steady=0.1)
    with pytest.raises(ValueError, match="steady fraction"):
        add_speed_noise(key, frames, nt, mask, std=0.2, current=3, steady=-0.1)
    with pytest.raises(ConfigError, match="--speed-noise-steady .* needs --speed-noise"):
        TrainConfig(speed_noise_steady=0.1)
    assert TrainConfig(speed_noise=0.3, speed_noise_steady=0.1).speed_noise_steady == 0.1
    from thrombojax.cli import build_parser

    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--speed-noise-steady", "0.1"])
    assert args.speed_noise_steady == 0.1


SPEEDS = (0.04, 0.05, 0.06)


def _batch():
    """Clots that keep their speed (:data:`SPEEDS` per frame), one window each."""
    return window_batch([_window(v, seed=i) for i, v in enumerate(SPEEDS)])


def test_the_training_loss_uses_the_speed_noise():
    from thrombojax.train.step import batch_loss

    batch, step = _batch(), tiny_mgn_step()
    params = step.init(jax.random.key(0), batch.frames[0, 0], batch.frames[0, 1],
                       batch.node_type[0], batch.mask[0])
    losses = [float(batch_loss(step, params, STATS, batch, jax.random.key(1), train=True,
                               speed_noise=s)[0]) for s in (0.0, 0.0, 0.2)]
    assert losses[0] == losses[1] != losses[2]
    # on steady windows only: clots that speed up by 29-40 % to s_t+1 keep their true motion
    speeding = window_batch([ring_clot_window(v, 0.02, shear=0.01, seed=i)
                             for i, v in enumerate(SPEEDS)])
    clean, noisy, steady = (
        float(batch_loss(step, params, STATS, speeding, jax.random.key(1), train=True,
                         speed_noise=s, speed_noise_steady=f)[0])
        for s, f in ((0.0, 0.0), (0.2, 0.0), (0.2, 0.1)))
    assert clean == steady != noisy


def _carry_after_training(speed_noise: float) -> float:
    """Train the tiny step on clots that keep their speed (0.04, 0.05 or 0.06 per frame), then
    return the share of a 5 % speed error in its inputs that its prediction keeps."""
    step = tiny_mgn_step()
    params = train_tiny_step(step, _batch(), STATS, speed_noise=speed_noise)
    frames, nt, mask = _window(0.05, seed=7)
    return float(speed_carry(step, params, STATS, np.asarray(frames), np.asarray(nt),
                             [1, 2], delta=0.05, mask=np.asarray(mask)).mean())


def test_speed_noise_teaches_a_model_to_bring_a_speed_error_back():
    """Fails without the noise: trained on clots that keep their speed, the model keeps a speed
    error it is given (as constant velocity does, carry near 1); with the noise (std 0.3 of the
    motion, above the spread of the training speeds) it pulls most of it back."""
    without = _carry_after_training(0.0)
    assert without > 0.7
    assert _carry_after_training(0.3) < 0.5 * without


def test_speed_carry_of_constant_velocity_is_one_and_bad_values_are_refused():
    from thrombojax.models.registry import create_model, identity_stats
    from thrombojax.simulator.step import make_step

    frames, nt, mask = (np.asarray(a) for a in _window(0.05, frames=5))
    cv = make_step(create_model("constant_velocity"))
    np.testing.assert_allclose(speed_carry(cv, {}, identity_stats(), frames, nt, [1, 2, 3],
                                           delta=0.05, mask=mask), 1.0, rtol=1e-3)
    with pytest.raises(ConfigError, match="delta"):
        speed_carry(cv, {}, identity_stats(), frames, nt, [1], delta=0.0)
    still = np.repeat(frames[:1], 3, axis=0)
    with pytest.raises(ConfigError, match="does not move at frame 1"):
        speed_carry(cv, {}, identity_stats(), still, nt, [1], delta=0.05, mask=mask)
