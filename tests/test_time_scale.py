"""Time scaling: each training window's clot motion played k times as fast (an augmentation).

A dataset whose runs are resampled to a fixed frame count moves its clot a set distance per
frame (the ladder's BendVessel: 0.27-0.34 vessel radii); a longer vessel, another frame rate or
a clot driven faster moves it more, outside every training window. The time scaling
(:func:`thrombojax.train.noise.time_scale_window`) plays each window ``k`` times as fast
(velocities ``k``, accelerations ``k^2`` times) so those speeds are in the training data.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import tiny_mgn_step, train_tiny_step
from test_speed_noise import STATS, _batch, _window

from thrombojax.errors import ConfigError
from thrombojax.train.config import TrainConfig
from thrombojax.train.noise import time_scale_window
from thrombojax.types import NodeType


def test_time_scaling_scales_velocities_by_k_and_accelerations_by_k_squared():
    rng = np.random.default_rng(0)
    frames = np.cumsum(rng.normal(size=(5, 9, 3)), axis=0).astype(np.float32)
    nt = np.array([NodeType.VESSEL] * 3 + [NodeType.CLOT] * 6, np.int32)
    mask = np.arange(9) < 8  # the last node is padding
    out = np.asarray(time_scale_window(jax.random.key(3), jnp.asarray(frames), jnp.asarray(nt),
                                       jnp.asarray(mask), factor=2.0, current=2))
    clot = (nt == NodeType.CLOT) & mask
    v, vo = np.diff(frames, axis=0)[:, clot], np.diff(out, axis=0)[:, clot]
    k = vo[1, 0, 0] / v[1, 0, 0]  # the current velocity v_t = s_2 - s_1
    assert 0.5 <= k <= 2.0 and abs(k - 1.0) > 1e-3
    np.testing.assert_allclose(vo[1], k * v[1], rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(np.diff(vo, axis=0), k * k * np.diff(v, axis=0), rtol=1e-4,
                               atol=1e-4)
    np.testing.assert_allclose(out[2], frames[2], atol=1e-6)  # s_t stays
    np.testing.assert_array_equal(out[:, ~clot], frames[:, ~clot])  # vessel and padding stay


def test_time_scaling_off_and_bad_values():
    frames, nt, mask = _window(0.05)
    assert time_scale_window(jax.random.key(0), frames, nt, mask, factor=1.0, current=1) \
        is frames
    with pytest.raises(ValueError, match="factor must be >= 1"):
        time_scale_window(jax.random.key(0), frames, nt, mask, factor=0.5, current=1)
    with pytest.raises(ConfigError, match="time_scale"):
        TrainConfig(time_scale=0.5)
    from thrombojax.cli import build_parser

    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--time-scale", "1.5"])
    assert args.time_scale == 1.5


def _error_at_unseen_speed(time_scale: float) -> float:
    """Train the tiny step on clots that keep their speed (0.04-0.06 per frame), then return the
    RMS of its predicted clot acceleration (the truth's is 0) for a clot at 0.1 per frame."""
    from thrombojax.eval.single_step import batched_next

    step = tiny_mgn_step()
    params = train_tiny_step(step, _batch(), STATS, time_scale=time_scale)
    frames, nt, mask = _window(0.1, seed=7)
    nxt = batched_next(step, params, STATS, frames[None, 1], frames[None, 2], nt, mask)[0]
    clot = np.asarray((nt == NodeType.CLOT) & mask)
    accel = np.asarray(nxt - 2 * frames[2] + frames[1])[clot]
    return float(np.sqrt(np.mean(accel**2)))


def test_time_scaling_teaches_a_model_speeds_beyond_the_data():
    """Fails without it: trained on clots at 0.04-0.06 per frame, the model gives a clot at 0.1
    per frame (faster than any training clot) an acceleration it does not have; with windows
    played up to 2x faster that speed is in the training data and the error drops."""
    without = _error_at_unseen_speed(1.0)
    assert _error_at_unseen_speed(2.0) < 0.5 * without
