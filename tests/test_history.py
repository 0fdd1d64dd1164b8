"""The step's history (``make_step(model, history=H)``): the accelerations before t as inputs.

The dynamics carry state one velocity does not show (a drive ramping in time, damping and
friction that differ per simulation); the previous acceleration is its witness. Tested: the
features, the frames a step reads from a trajectory, that the losses and the rollout carry the
history exactly like a hand-written loop, the option through the config and the CLI, and a
learning test that fails without it (a hidden per-simulation acceleration).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from dataset_factory import rollout_state

from thrombojax.data.batching import Batch
from thrombojax.errors import ConfigError
from thrombojax.models.registry import create_model, get_config
from thrombojax.simulator.ensemble import ensemble_rollout, stack_params
from thrombojax.simulator.rollout import rollout, unroll
from thrombojax.simulator.step import make_step, past_accelerations, target_acceleration
from thrombojax.train.config import TrainConfig
from thrombojax.train.loss import window_loss_terms
from thrombojax.train.noise import add_training_noise
from thrombojax.train.step import init_state, make_train_step
from thrombojax.types import NodeType, TargetStats

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)


def _trajectory(n_frames=7, seed=0):
    """``[T, N, 3]`` frames: rollout_state's cloud with its clot nodes accelerating."""
    x_prev, x_cur, nt, mask, stats = rollout_state(seed=seed)
    rng = np.random.default_rng(seed)
    acc = 0.002 * rng.normal(size=x_cur.shape).astype(np.float32)
    clot = (nt == NodeType.CLOT)[:, None]
    t = np.arange(n_frames, dtype=np.float32)[:, None, None]
    traj = x_cur[None] + clot * (0.01 * t + acc * t**2)
    return traj.astype(np.float32), nt, mask, stats


def _model():
    return create_model("mgn", get_config("mgn", tiny=True, max_neighbors=6))


def test_past_accelerations_and_previous_frames():
    traj, nt, mask, stats = _trajectory()
    step = make_step(_model(), history=3)
    prev = step.previous(traj, 4)
    np.testing.assert_array_equal(prev, traj[1:4])
    feats = np.asarray(past_accelerations(prev, traj[4], mask, 2.0))
    a2, a3 = (target_acceleration(traj[t - 1], traj[t], traj[t + 1]) for t in (2, 3))
    want = np.concatenate([a2, a3], axis=1) / 2.0
    want[~mask] = 0.0
    np.testing.assert_allclose(feats, want, rtol=1e-5, atol=1e-7)
    # before the record starts the clot is at rest: frame 0 is repeated
    np.testing.assert_array_equal(step.previous(traj, 1), traj[[0, 0, 0]])
    np.testing.assert_array_equal(step.previous(traj, np.array([1, 5]))[1], traj[2:5])
    np.testing.assert_array_equal(make_step(_model()).previous(traj, 3), traj[2])
    with pytest.raises(ConfigError, match="no previous frame"):
        step.previous(traj, 0)
    with pytest.raises(ConfigError, match="history"):
        make_step(_model(), history=0)


def test_a_history_step_reads_the_previous_acceleration():
    """History 2 grows the node encoder by 3 inputs, and the output moves with s_{t-2}; the
    one-velocity step never sees s_{t-2}."""
    traj, nt, mask, stats = _trajectory()
    one, two = make_step(_model()), make_step(_model(), history=2)
    p1 = one.init(jax.random.key(0), traj[2], traj[3], nt, mask)
    p2 = two.init(jax.random.key(0), traj[1:3], traj[3], nt, mask)
    k1 = p1["params"]["node_encoder"]["dense_0"]["kernel"]
    k2 = p2["params"]["node_encoder"]["dense_0"]["kernel"]
    assert k2.shape[0] == k1.shape[0] + 3
    out = two(p2, stats, traj[1:3], traj[3], nt, mask)
    other = traj[1:3].copy()
    other[0] += 0.01 * (nt == NodeType.CLOT)[:, None]
    moved = two(p2, stats, other, traj[3], nt, mask)
    assert not np.allclose(out.output, moved.output)
    # the integration uses s_{t-1} only: same output -> same update as history 1 would give
    v = traj[3] - traj[2]
    acc = stats.denormalize(out.output)
    clot = ((nt == NodeType.CLOT) & mask)[:, None]
    np.testing.assert_allclose(out.positions, np.where(clot, traj[3] + v + acc, traj[3]),
                               rtol=1e-6, atol=1e-6)


def test_history_losses_and_rollouts_match_a_hand_written_loop():
    traj, nt, mask, stats = _trajectory()
    step = make_step(_model(), history=2)
    params = step.init(jax.random.key(1), traj[0:2], traj[2], nt, mask)
    # rollout: the history is shifted every step
    pred = np.asarray(rollout(step, params, stats, traj[0:2], traj[2], nt, mask, 3))
    prev, cur, mine = traj[0:2], traj[2], []
    for _ in range(3):
        nxt = step(params, stats, prev, cur, nt, mask).positions
        prev, cur = np.stack([prev[1], cur]), nxt
        mine.append(nxt)
    np.testing.assert_allclose(pred, np.stack(mine), rtol=1e-5, atol=1e-6)
    # the k-step loss on a window (s_{t-2}, s_{t-1}, s_t, s_{t+1}, s_{t+2})
    window = jnp.asarray(traj[0:5])
    terms = window_loss_terms(step, params, stats, window, nt, mask, k=2, train=False, rng=None)
    s1, s2 = mine[0], step(params, stats, np.stack([traj[1], traj[2]]), mine[0], nt,
                           mask).positions
    clot = ((nt == NodeType.CLOT) & mask)[:, None]
    mse = 0.5 * sum(float(np.where(clot, (p - t) ** 2, 0).mean(1).sum())
                    for p, t in ((s1, traj[3]), (s2, traj[4])))
    np.testing.assert_allclose(float(terms["mse_sum"]), mse, rtol=1e-4)
    with pytest.raises(ValueError, match="window"):
        window_loss_terms(step, params, stats, window[:4], nt, mask, k=2, train=False,
                          rng=None)
    # push-forward: one step without gradients, then the loss from the model's own state
    pf = window_loss_terms(step, params, stats, window, nt, mask, k=1, pushforward=1,
                           train=False, rng=None)
    s2_mse = float(np.where(clot, (np.asarray(s2) - traj[4]) ** 2, 0).mean(1).sum())
    np.testing.assert_allclose(float(pf["mse_sum"]), s2_mse, rtol=1e-4)
    # the differentiable unroll and a 2-member ensemble of one model agree with the rollout
    np.testing.assert_allclose(unroll(step, params, stats, traj[0:2], traj[2], nt, mask, 3)[0],
                               pred, rtol=1e-5, atol=1e-6)
    ens = ensemble_rollout(step, stack_params([params, params]), stats, traj[0:2], traj[2], nt,
                           mask, 3)
    np.testing.assert_allclose(ens.mean, pred, rtol=1e-5, atol=1e-6)
    with pytest.raises(ConfigError, match="x_prev"):
        rollout(step, params, stats, traj[1], traj[2], nt, mask, 3)


def test_noise_lands_on_the_current_frame():
    traj, nt, mask, _ = _trajectory()
    noisy = np.asarray(add_training_noise(jax.random.key(0), jnp.asarray(traj[:5]), nt, mask,
                                          std=0.1, gamma=0.0, current=2))
    np.testing.assert_array_equal(noisy[:2], traj[:2])  # the history stays exact
    n = noisy[2] - traj[2]
    assert np.abs(n).max() > 0
    np.testing.assert_allclose(noisy[3:] - traj[3:5], np.stack([n, n]), atol=1e-6)


def test_config_window_length_and_cli_option():
    cfg = TrainConfig(history=3, rollout_steps=2, pushforward_steps=1)
    assert cfg.window_length == 1 + 2 + 3 + 1
    assert TrainConfig().window_length == 3
    with pytest.raises(ConfigError, match="history"):
        TrainConfig(history=0)
    from thrombojax.cli import build_parser

    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--history", "2"])
    assert args.history == 2


def _hidden_acceleration_batch(history: int, n_sims: int = 8, n_frames: int = 9):
    """Windows of simulations whose clot moves along x with a constant acceleration of either
    sign, the velocities of both signs spanning the same range: one velocity cannot tell the
    acceleration, the previous acceleration is it."""
    _, x0, nt, mask, _ = rollout_state(n=24)
    clot = (nt == NodeType.CLOT) & mask
    frames, c = [], 0.002
    t = np.arange(n_frames, dtype=np.float32)
    for i in range(n_sims):
        sign = 1.0 if i % 2 else -1.0
        v0 = 0.0 if sign > 0 else c * (n_frames - 1)
        shift = v0 * t + sign * 0.5 * c * t**2 + 0.05 * i
        traj = np.repeat(x0[None], n_frames, axis=0)
        traj[:, clot, 0] += shift[:, None]
        length = history + 2
        frames += [traj[s:s + length] for s in range(n_frames - length + 1)]
    frames = np.stack(frames).astype(np.float32)
    b = frames.shape[0]
    batch = Batch(frames=frames, node_type=np.repeat(nt[None], b, 0),
                  mask=np.repeat(mask[None], b, 0), generated=np.zeros(b, bool))
    stats = TargetStats(mean=jnp.zeros(3), std=jnp.full(3, c), velocity_std=jnp.asarray(0.01))
    return batch, stats


@pytest.mark.parametrize("steps", [150])
def test_history_learns_a_hidden_acceleration_one_velocity_cannot(steps):
    """Fails without the history: trained alike, the one-velocity model keeps a loss near the
    target's variance (it cannot tell the sign), the two-frame model learns it."""
    losses = {}
    for history in (1, 2):
        batch, stats = _hidden_acceleration_batch(history)
        step = make_step(_model(), history=history)
        tx = optax.adam(3e-3)
        state = init_state(step, tx, jax.random.key(0), batch)
        train_step = make_train_step(step, tx, stats, donate=False)
        for i in range(steps):
            state, metrics = train_step(state, batch, jax.random.key(i))
        losses[history] = float(metrics["loss"])
    assert losses[2] < 0.1 * losses[1], losses
    assert losses[1] > 0.1, losses


def test_extrapolation_baselines_score_a_constant_acceleration_exactly(tmp_path):
    """experiments/extrapolation.py: constant acceleration is exact on a uniformly
    accelerating clot (CV is not), and the script writes its table with the environment."""
    import importlib.util
    import pathlib

    from dataset_factory import accelerating_sims

    from thrombojax.io.hdf5 import write_dataset

    root = pathlib.Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("extrapolation",
                                                  root / "experiments" / "extrapolation.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    traj, nt, mask, _ = _trajectory(n_frames=8)
    errs = module.one_step_errors(traj, (nt == NodeType.CLOT) & mask, skip=0)
    assert errs["constant acceleration"] < 1e-10 < errs["constant velocity"]
    data = write_dataset(tmp_path / "acc.h5", accelerating_sims(n_sims=2, n_nodes=40,
                                                                 n_frames=6),
                         name="acc", source="test")
    out = tmp_path / "extra"
    assert module.main(["--dataset", str(data), "--out", str(out)]) == 0
    text = (out / "table.md").read_text()
    assert "constant acceleration" in text and "- jax:" in text
    with pytest.raises(Exception, match="exists|force"):
        module.main(["--dataset", str(data), "--out", str(out)])


def test_cli_trains_a_history_step_and_every_consumer_reads_it(tmp_path):
    """`thrombojax train --history 2`: the run records it, the loaded step reads two frames,
    and `evaluate`, `rollout` and `bench` (on the dataset's frames and on the synthetic tube)
    run through it."""
    import json

    from dataset_factory import train_tiny_cli

    from thrombojax.cli import main
    from thrombojax.eval.report import rollout_run
    from thrombojax.train.state import load_trained

    data, run = train_tiny_cli(tmp_path, "--history", "2")
    loaded = load_trained(run)
    assert loaded.run.train.history == 2 and loaded.step.history == 2
    assert main(["evaluate", "--run", str(run), "--dataset", str(data), "--out",
                 str(tmp_path / "eval"), "--quiet"]) == 0
    report = rollout_run(run, data, tmp_path / "rollout", progress=False, gif=False)
    sims = report["simulations"]
    assert sims and all("NaN" not in json.dumps(r["summary"]) for r in sims.values())
    from thrombojax.eval.bench import bench

    for source in (str(data), None):
        timed = bench(models=("mgn",), cases=("bendvessel",), runs={"mgn": str(run)},
                      n_nodes=60, max_steps=2, repeats=1, dataset=source, progress=False)
        assert timed["results"][0]["weights"] == "trained" and timed["results"][0]["finite"]


def test_random_walk_noise_over_the_history():
    """walk=True: every input frame after the first is corrupted by the integral of a random
    walk of velocity noise; the targets move by (1 - gamma) of s_t's noise; H = 1 is the plain
    noise exactly."""
    traj, nt, mask, _ = _trajectory()
    frames = jnp.asarray(traj[:5])
    key = jax.random.key(3)
    walked = np.asarray(add_training_noise(key, frames, nt, mask, std=0.1, gamma=0.25,
                                           current=2, walk=True))
    p = walked - traj[:5]
    np.testing.assert_array_equal(p[0], 0.0)  # s_{t-2} exact
    clot = (nt == NodeType.CLOT) & mask
    assert np.abs(p[1][clot]).max() > 0 and np.abs(p[2][clot] - p[1][clot]).max() > 0
    np.testing.assert_array_equal(p[:, ~clot], 0.0)  # vessel and padding untouched
    np.testing.assert_allclose(p[3:], np.stack([0.75 * p[2]] * 2), atol=1e-6)
    # velocity noise: increments of std / sqrt(H), cumulative, so v_t's noise has std ~ std
    big = jnp.zeros((4, 20000, 3))
    many = np.asarray(add_training_noise(key, big, np.full(20000, NodeType.CLOT),
                                         np.ones(20000, bool), std=0.1, current=2, walk=True))
    v_t = many[2] - many[1]
    assert abs(v_t.std() - 0.1) < 0.005 and abs(many[1].std() - 0.1 / np.sqrt(2)) < 0.005
    plain = add_training_noise(key, frames, nt, mask, std=0.1, current=1)
    np.testing.assert_array_equal(plain, add_training_noise(key, frames, nt, mask, std=0.1,
                                                            current=1, walk=True))
    with pytest.raises(ConfigError, match="noise_walk"):
        TrainConfig(noise_walk=1)


def test_stop_history_gradient_cuts_only_the_history_path():
    """With the flag the oldest frame (which reaches the model only through the acceleration
    feature) gets no gradient; the outputs and the other inputs' gradients are unchanged in
    kind; the option travels through the config."""
    traj, nt, mask, stats = _trajectory()
    plain = make_step(_model(), history=2)
    cut = make_step(_model(), history=2, stop_history_gradient=True)
    params = plain.init(jax.random.key(0), traj[0:2], traj[2], nt, mask)

    def grads(step):
        def f(prev, cur):
            return jnp.sum(step(params, stats, prev, cur, nt, mask).output ** 2)
        return jax.jit(jax.grad(f, argnums=(0, 1)))(jnp.asarray(traj[0:2]), jnp.asarray(traj[2]))

    (gp_plain, _), (gp_cut, gc_cut) = grads(plain), grads(cut)
    assert np.abs(np.asarray(gp_plain[0])).max() > 0
    np.testing.assert_array_equal(np.asarray(gp_cut[0]), 0.0)
    assert np.abs(np.asarray(gc_cut)).max() > 0  # positions and velocity still differentiate
    np.testing.assert_allclose(cut(params, stats, traj[0:2], traj[2], nt, mask).output,
                               plain(params, stats, traj[0:2], traj[2], nt, mask).output)
    assert TrainConfig(history=2, stop_history_gradient=True).stop_history_gradient
    with pytest.raises(ConfigError, match="stop_history_gradient"):
        TrainConfig(stop_history_gradient="yes")
