"""The clot's start speed: a learned step that also reads the clot's speed in the true frames its
rollout starts from (``make_step(..., start_speed=True)``, ``thrombojax train --start-speed``;
:mod:`thrombojax.simulator.start_speed`).

A step trained with speed noise learns to take its speed from somewhere other than the motion it
is shown; without the start speed it can only take the training simulations' speeds, with it the
simulation's own, from true frames a rollout keeps (the start frames never move with the model's
output)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import ring_clot_window, tiny_mgn_step, train_tiny_step, window_batch
from test_rest_edges import _mgn, _scene
from test_speed_noise import STATS

from thrombojax.errors import ConfigError
from thrombojax.eval.drift import speed_carry
from thrombojax.models.registry import identity_stats
from thrombojax.simulator.rollout import unroll
from thrombojax.simulator.start_speed import scale_start_speed, start_speed_feature
from thrombojax.simulator.step import make_step
from thrombojax.types import NodeType


@pytest.mark.parametrize("history,rest", [(1, False), (3, False), (2, True)])
def test_previous_carries_the_start_frames_of_the_rollout_and_shift_keeps_them(history, rest):
    """``x_prev`` = (rest), s_{c-1}, s_c, then the history; ``c = t`` (a rollout from t) or
    ``min(t, start_from)`` (a window after the rollouts' start frame); a rollout keeps them."""
    pos, nt, _ = _scene(frames=8)
    step = make_step(_mgn(), history=history, rest_edges=rest, start_speed=True)
    lead = [pos[0]] if rest else []
    hist = [pos[max(5 - j, 0)] for j in range(history, 0, -1)]
    np.testing.assert_array_equal(np.asarray(step.previous(pos, 5)),
                                  np.stack([*lead, pos[4], pos[5], *hist]))
    np.testing.assert_array_equal(np.asarray(step.previous(pos, 5, start_from=2)),
                                  np.stack([*lead, pos[1], pos[2], *hist]))
    many = np.asarray(step.previous(pos, np.array([1, 6]), start_from=3))
    assert many.shape == (2, len(lead) + 2 + history, len(nt), 3)
    np.testing.assert_array_equal(many[:, len(lead):len(lead) + 2],
                                  np.stack([pos[0:2], pos[2:4]]))  # c = 1, then 3
    prev = step.previous(pos, 3)
    np.testing.assert_array_equal(np.asarray(step.last_previous(prev)), pos[2])
    nxt = np.asarray(step.shift(jnp.asarray(prev), jnp.asarray(pos[3])))
    np.testing.assert_array_equal(nxt, np.asarray(step.previous(pos, 4, start_from=3)))
    step.check_previous(prev, len(nt), "test")
    with pytest.raises(ConfigError, match="start frames"):
        step.check_previous(np.asarray(prev)[1:], len(nt), "test")


def test_the_start_speed_feature_is_the_clot_speed_on_clot_nodes_only_and_turns_with_nothing():
    frames, nt, mask = ring_clot_window(0.05)
    feat = np.asarray(start_speed_feature(frames[:2], nt, mask, 0.025))
    clot = np.asarray((nt == NodeType.CLOT) & mask)
    np.testing.assert_allclose(feat[clot, 0], 2.0, rtol=1e-4)  # 0.05 per frame / 0.025
    assert not feat[~clot].any()
    rot, _ = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))
    turned = jnp.asarray(np.asarray(frames[:2]) @ rot.T + 3.0)
    np.testing.assert_allclose(np.asarray(start_speed_feature(turned, nt, mask, 0.025)), feat,
                               rtol=1e-4)


def test_the_step_reads_the_start_speed_and_a_rollout_keeps_it():
    """Another start speed changes the step's output; a rollout's steps equal single steps whose
    start frames are the start's (``start_from``), not the predicted frames'."""
    pos, nt, mask = _scene(frames=8)
    step = make_step(_mgn(), start_speed=True)
    params = step.init(jax.random.key(0), step.previous(pos, 1), pos[1], nt, mask)
    stats = identity_stats()
    slow = pos.copy()
    slow[2] = pos[1] + 0.5 * (pos[2] - pos[1])  # a slower clot in frame 2 alone
    a = step(params, stats, step.previous(pos, 4, start_from=2), pos[4], nt, mask).output
    b = step(params, stats, step.previous(slow, 4, start_from=2), pos[4], nt, mask).output
    assert float(jnp.abs(a - b).max()) > 1e-4
    traj, _ = unroll(step, params, stats, step.previous(pos, 2), pos[2], nt, mask, 3)
    full = np.concatenate([pos[:3], np.asarray(traj)])
    for i in range(3):
        one = step(params, stats, step.previous(full, 2 + i, start_from=2), full[2 + i], nt,
                   mask).positions
        np.testing.assert_allclose(np.asarray(traj[i]), np.asarray(one), atol=1e-5)


def test_batches_lead_with_the_start_frames_of_the_rollout_start():
    """``make_batch(..., start_speed=(start, H))``: a window whose frame t is before ``start`` reads
    its own s_{t-1}, s_t; a later one the frames ``start - 1, start``; the same nodes."""
    from dataset_factory import numbered_store

    from thrombojax.data.batching import make_batch

    store = numbered_store(9)  # y: the frame number
    times = [store.windows[i][1] for i in range(len(store))]
    entries = np.array([[times.index(2), 0], [times.index(6), 0]])  # frame t = 2 and 6
    plain = make_batch(store, entries, 64, nodes_per_sample=20, seed=1)
    led = make_batch(store, entries, 64, nodes_per_sample=20, seed=1, start_speed=(4, 1))
    both = make_batch(store, entries, 64, nodes_per_sample=20, seed=1, rest=True,
                      start_speed=(4, 1))
    np.testing.assert_array_equal(led.frames[:, 2:], plain.frames)
    np.testing.assert_array_equal(both.frames[:, 1:], led.frames)
    real = plain.mask
    for b, (c0, c1) in enumerate(((1, 2), (3, 4))):
        np.testing.assert_array_equal(led.frames[b, :2, :, 1][:, real[b]],
                                      np.array([[c0], [c1]]) * np.ones((1, real[b].sum())))
        np.testing.assert_array_equal(led.frames[b, 0, :, 0], plain.frames[b, 0, :, 0])


SPEEDS = (0.03, 0.05, 0.07)


def _carry_after_training(start_speed: bool) -> float:
    """Train the tiny step with speed noise 0.3 on clots that keep their speed (:data:`SPEEDS`,
    the windows led by their first two frames when it reads the start speed), then return the share
    of a 10 % speed error in its inputs that its prediction keeps (the start frames true)."""
    step = make_step(tiny_mgn_step().model, start_speed=start_speed)
    windows = [ring_clot_window(v, shear=0.01, seed=i) for i, v in enumerate(SPEEDS)]
    if start_speed:
        windows = [(jnp.concatenate([f[:2], f]), nt, m) for f, nt, m in windows]
    params = train_tiny_step(step, window_batch(windows), STATS, speed_noise=0.3)
    frames, nt, mask = ring_clot_window(0.04, shear=0.01, seed=7)
    return float(speed_carry(step, params, STATS, np.asarray(frames), np.asarray(nt), [1, 2],
                             delta=0.1, mask=np.asarray(mask)).mean())


def test_the_start_speed_lets_a_step_trained_with_speed_noise_keep_the_simulation_speed():
    """Fails without the start speed: with speed noise a step learns to bring a speed error back but
    can only bring it to a speed of its training; reading the true start speed it drops the error in
    its inputs for the clot's own speed, keeping much less of it."""
    without = _carry_after_training(False)
    assert _carry_after_training(True) < 0.5 * without


def test_the_option_reaches_the_config_cli_and_is_refused_where_it_cannot_act():
    from thrombojax.cli import build_parser
    from thrombojax.simulator.flat import FlatStep, flat_batch_ok
    from thrombojax.train.config import TrainConfig

    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--start-speed"])
    assert args.start_speed is True
    assert TrainConfig(start_speed=True).start_speed
    with pytest.raises(ConfigError, match="start_speed"):
        TrainConfig(start_speed="yes")
    with pytest.raises(ConfigError, match="--start-speed .* --pushforward-guards"):
        TrainConfig(start_speed=True, input_guards=True)
    step = make_step(tiny_mgn_step().model, start_speed=True)
    assert not flat_batch_ok(step)
    with pytest.raises(ConfigError, match="start frames"):
        FlatStep(step)


def test_cli_trains_with_the_start_speed_reloads_the_step_and_rolls_out(tmp_path):
    from dataset_factory import train_tiny_cli

    from thrombojax.cli import main
    from thrombojax.train.state import load_trained

    data, run = train_tiny_cli(tmp_path, "--start-speed", "--rollout-steps", "2", n_nodes=80)
    loaded = load_trained(run)
    assert loaded.run.train.start_speed is True and loaded.step.start_speed
    out = tmp_path / "ro"
    assert main(["rollout", "--run", str(run), "--dataset", str(data), "--out", str(out),
                 "--split", "test", "--no-gif", "--quiet"]) == 0
    assert (out / "rollout.json").exists()


def test_start_speed_noise_scales_the_start_motion_by_one_factor_and_nothing_else():
    from thrombojax.simulator.start_speed import jitter_start_speed

    frames, nt, mask = ring_clot_window(0.05, shear=0.01, frames=4)
    lead = jnp.concatenate([frames[:1], frames[:2]])  # a rest frame, then the two start frames
    out = np.asarray(jitter_start_speed(jax.random.key(3), lead, 0.2))
    f = np.asarray(lead)
    np.testing.assert_array_equal(out[:2], f[:2])  # the rest frame and s_{c-1} stay
    motion, noisy = f[2] - f[1], out[2] - out[1]
    factor = noisy[20, 0] / motion[20, 0]
    assert abs(factor - 1.0) > 1e-3
    np.testing.assert_allclose(noisy, factor * motion, atol=2e-6)  # one factor, every node
    before = start_speed_feature(lead[1:], nt, mask, 0.05)
    after = start_speed_feature(jnp.asarray(out[1:]), nt, mask, 0.05)
    clot = np.asarray((nt == NodeType.CLOT) & mask)
    np.testing.assert_allclose(np.asarray(after)[clot], abs(factor) * np.asarray(before)[clot],
                               rtol=1e-4)
    assert jitter_start_speed(jax.random.key(3), lead, 0.0) is lead
    with pytest.raises(ValueError, match="std must be >= 0"):
        jitter_start_speed(jax.random.key(3), lead, -0.1)
    with pytest.raises(ValueError, match="two start frames last"):
        jitter_start_speed(jax.random.key(3), lead[0], 0.1)


def test_start_speed_noise_acts_in_training_only():
    """The training loss of a step with the start speed changes with the noise; the evaluation
    loss (no noise) and a step without the start speed do not."""
    from thrombojax.train.schedule import make_optimizer
    from thrombojax.train.step import batch_loss, init_state

    windows = [ring_clot_window(v, shear=0.01, seed=i) for i, v in enumerate(SPEEDS)]
    plain = window_batch(windows)
    led = window_batch([(jnp.concatenate([f[:2], f]), nt, m) for f, nt, m in windows])
    step, without = make_step(tiny_mgn_step().model, start_speed=True), tiny_mgn_step()
    params = init_state(step, make_optimizer(1e-3), jax.random.key(0), led).params
    params0 = init_state(without, make_optimizer(1e-3), jax.random.key(0), plain).params

    def loss(train, noise, s=step, p=params, batch=led):
        key = jax.random.key(5) if train else None
        return float(batch_loss(s, p, STATS, batch, key, train=train, speed_noise=0.1,
                                start_speed_noise=noise)[0])

    assert loss(True, 0.3) != loss(True, 0.0)
    assert loss(False, 0.3) == loss(False, 0.0)
    assert loss(True, 0.3, without, params0, plain) == loss(True, 0.0, without, params0, plain)


SLOW_FAST = (0.03, 0.07)


def _start_gain_after_training(start_speed_noise: float) -> float:
    """Train the tiny step that reads the start speed with speed noise 0.3 on two clots that keep
    their speeds (:data:`SLOW_FAST`), with the start-speed noise given; return the share of a
    10 % faster start speed its predicted clot motion takes on (clean inputs)."""
    step = make_step(tiny_mgn_step().model, start_speed=True)
    windows = [ring_clot_window(v, shear=0.01, seed=i) for i, v in enumerate(SLOW_FAST)]
    windows = [(jnp.concatenate([f[:2], f]), nt, m) for f, nt, m in windows]
    params = train_tiny_step(step, window_batch(windows), STATS, speed_noise=0.3,
                             start_speed_noise=start_speed_noise)
    frames, nt, mask = ring_clot_window(0.05, shear=0.01, seed=7)
    x_prev = step.previous(frames, 1, start_from=1)  # start frames s_0, s_1; then s_0
    faster = scale_start_speed(x_prev, 1.1)
    clot = np.asarray((nt == NodeType.CLOT) & mask)
    moves = [np.asarray(step(params, STATS, p, frames[1], nt, mask).positions - frames[1])
             [clot, 0].mean() for p in (x_prev, faster)]
    return (moves[1] / moves[0] - 1.0) / 0.1


def test_start_speed_noise_keeps_the_step_from_leaning_on_the_start_speed_alone():
    """Fails without the noise: a step trained with speed noise on its input motion but a clean
    start speed takes its speed from the start speed (a 10 % faster start, a clot about 10 %
    faster); with the start speed noised as much as the motion it takes on clearly less."""
    clean = _start_gain_after_training(0.0)
    noisy = _start_gain_after_training(0.3)
    assert clean > 0.5
    assert noisy < 0.7 * clean


def test_start_speed_noise_reaches_the_config_cli_and_step_and_needs_the_start_speed():
    from thrombojax.cli import build_parser
    from thrombojax.train.config import TrainConfig
    from thrombojax.train.step_options import train_step_options

    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--start-speed", "--start-speed-noise", "0.2"])
    assert args.start_speed_noise == 0.2
    cfg = TrainConfig(start_speed=True, start_speed_noise=0.2)
    assert train_step_options(cfg, 1.0, 10)["start_speed_noise"] == 0.2
    assert train_step_options(TrainConfig(), 1.0, 10)["start_speed_noise"] == 0.0
    with pytest.raises(ConfigError, match="--start-speed-noise .* needs --start-speed"):
        TrainConfig(start_speed_noise=0.2)
    with pytest.raises(ConfigError, match="start_speed_noise"):
        TrainConfig(start_speed=True, start_speed_noise=-0.1)
