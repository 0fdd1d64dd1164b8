"""The speed-up weight: training windows whose true clot speeds up weigh more in the loss.

A BendVessel clot slides at a steady speed and speeds up only where it leaves the vessel, in a
few windows; a step trained on every window alike brakes there
(``experiments/results/ladder_budget/bendvessel_exit/README.md``).
:func:`thrombojax.train.speedup.speedup_window_weight` gives those windows the weight
``1 + W`` (``thrombojax train --speedup-weight W``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import ring_clot_window, tiny_mgn_step, train_tiny_step, window_batch

from thrombojax.errors import ConfigError
from thrombojax.train.config import TrainConfig
from thrombojax.train.speedup import clot_speeds, speedup_window_weight
from thrombojax.types import NodeType, TargetStats

STATS = TargetStats(mean=jnp.zeros(3), std=jnp.full(3, 0.02), velocity_std=jnp.asarray(0.05))


def test_a_window_weighs_more_only_where_its_clot_speeds_up_by_more_than_the_fraction():
    """At s_t = frame 2: steady, 5 % faster (within 0.1), 25 % faster, slowing down, resting,
    starting from rest. Padded nodes (typed clot, racing away, masked out) do not count."""
    cases = (((0.05, 0.0), 1.0), ((0.05, 0.0025), 1.0), ((0.05, 0.02), 4.0),
             ((0.05, -0.02), 1.0), ((0.0, 0.0), 1.0))
    for (speed, accel), expected in cases:
        frames, nt, mask = ring_clot_window(speed, accel, frames=4)
        pad = ~np.asarray(mask)
        frames = frames.at[:, pad].set(50.0 * jnp.arange(4.0)[:, None, None] ** 2)
        nt = nt.at[pad].set(NodeType.CLOT)
        weight = speedup_window_weight(frames, nt, mask, current=2, weight=3.0, fraction=0.1)
        assert float(weight) == expected, (speed, accel)
    # from rest: s_(t-1) = s_t, then the clot moves
    frames, nt, mask = ring_clot_window(0.05, frames=4)
    frames = frames.at[1].set(frames[2])
    assert float(speedup_window_weight(frames, nt, mask, current=2, weight=3.0,
                                       fraction=0.1)) == 4.0
    before, after = clot_speeds(*ring_clot_window(0.05, 0.02, frames=4), current=2)
    np.testing.assert_allclose([before, after], [0.08, 0.10], rtol=1e-5)
    with pytest.raises(ValueError, match="s_\\(t\\+1\\)"):
        clot_speeds(frames[:3], nt, mask, current=2)
    with pytest.raises(ValueError, match=">= 0"):
        speedup_window_weight(frames, nt, mask, current=2, weight=-1.0, fraction=0.1)


def test_config_and_cli_take_the_speedup_weight():
    assert TrainConfig(speedup_weight=3.0, speedup_fraction=0.2).speedup_weight == 3.0
    for field in ("speedup_weight", "speedup_fraction"):
        with pytest.raises(ConfigError, match=field):
            TrainConfig(**{field: -0.5})
    from thrombojax.cli import build_parser
    from thrombojax.train.step_options import train_step_options

    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--speedup-weight", "3", "--speedup-fraction", "0.2"])
    assert (args.speedup_weight, args.speedup_fraction) == (3.0, 0.2)
    options = train_step_options(TrainConfig(speedup_weight=3.0, speedup_fraction=0.2), 1.0, 10)
    assert (options["speedup_weight"], options["speedup_fraction"]) == (3.0, 0.2)


def _mixed_batch():
    """Two clots that keep their speed, one that speeds up by 33 % into s_t+1 (s_t = frame 1)."""
    return window_batch([ring_clot_window(0.05, seed=0), ring_clot_window(0.06, seed=1),
                         ring_clot_window(0.05, 0.02, seed=2)])


def test_the_loss_is_the_window_weighted_mean_and_the_mse_stays_plain():
    """With weight W the loss is ``sum_i w_i L_i n_i / sum_i w_i n_i`` of the windows' own
    losses ``L_i`` over ``n_i`` clot nodes; W = 0 gives the plain loss, and the MSE metric
    does not change with W."""
    from thrombojax.train.step import batch_loss

    batch, step = _mixed_batch(), tiny_mgn_step()
    params = step.init(jax.random.key(0), batch.frames[0, 0], batch.frames[0, 1],
                       batch.node_type[0], batch.mask[0])

    def loss(b, **kw):
        value, metrics = batch_loss(step, params, STATS, b, None, train=False, **kw)
        return float(value), float(metrics["mse"]), float(metrics["nodes"])

    alone = [loss(window_batch([(batch.frames[i], batch.node_type[i], batch.mask[i])]))
             for i in range(3)]
    w = np.array([1.0, 1.0, 4.0])
    n = np.array([a[2] for a in alone])
    expected = float((w * n * np.array([a[0] for a in alone])).sum() / (w * n).sum())
    plain, weighted = loss(batch), loss(batch, speedup_weight=3.0)
    assert weighted[0] == pytest.approx(expected, rel=1e-5)
    assert weighted[0] != pytest.approx(plain[0], rel=1e-3)
    assert weighted[1] == plain[1] and weighted[2] == plain[2]
    assert loss(batch, speedup_weight=0.0) == plain
    steady = window_batch([(batch.frames[i], batch.node_type[i], batch.mask[i]) for i in (0, 1)])
    assert loss(steady, speedup_weight=3.0)[0] == pytest.approx(loss(steady)[0], rel=1e-6)


def test_the_weight_teaches_a_step_the_window_where_the_clot_speeds_up():
    """Trained briefly on two steady clots and one that speeds up, the tiny step predicts the
    speeding clot's next frame better with the weight than without (same seed, same steps)."""
    from thrombojax.train.step import batch_loss

    batch, step = _mixed_batch(), tiny_mgn_step()
    speeding = window_batch([(batch.frames[2], batch.node_type[2], batch.mask[2])])
    errors = []
    for weight in (0.0, 9.0):
        params = train_tiny_step(step, batch, STATS, steps=60, speedup_weight=weight)
        errors.append(float(batch_loss(step, params, STATS, speeding, None, train=False)[1]
                            ["mse"]))
    assert errors[1] < 0.5 * errors[0], errors  # measured: 13x smaller
