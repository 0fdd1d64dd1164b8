"""Training on guarded states: with ``--pushforward-guards`` the pushed prediction passes through
coherence and containment before the loss step reads it, with ``--input-guards`` the window's
input frames do; both reach the training loop from the command line."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import radial, tiny_mgn_step, train_tiny_cli, tube_window, window_batch

from thrombojax.errors import ConfigError
from thrombojax.graph.wall_nodes import local_wall_plane
from thrombojax.train.config import TrainConfig
from thrombojax.train.loss import window_loss_terms
from thrombojax.train.push_guards import PushGuards, guard_frame, guard_inputs, guarded_push
from thrombojax.train.schedule import make_optimizer
from thrombojax.train.step import batch_loss, init_state
from thrombojax.types import NodeType, TargetStats

_STATS = TargetStats(mean=jnp.zeros(3), std=jnp.full(3, 0.01), velocity_std=0.05)
_LOOSE = 1e3  # a coherence tolerance nothing reaches: containment alone


def _tube(n_frames=5, n_clot=40, speed=0.05, seed=0):
    """A clot sliding along z in a straight tube of radius 1, half of its nodes at radius
    0.9-0.95: its frames ``[n_frames, N, 3]``, node types, mask, radii."""
    return tube_window(seed, n_clot, 0, speed, (0.9, 0.95), inner=0.5, z_range=(-0.6, 0.2),
                       n_frames=n_frames)


def test_containment_puts_back_what_crossed_the_wall_and_leaves_the_rest():
    frames, nt, mask, rho = _tube()
    truth = frames[2]
    clot = np.flatnonzero(nt == NodeType.CLOT)
    rim, deep = clot[rho >= 0.9], clot[rho < 0.5]
    out = truth.copy()
    out[clot] += 0.2 * radial(truth[clot])  # the rim nodes end about 0.1 outside the wall
    guards = PushGuards(margin=0.01, tolerance=_LOOSE)
    got = np.asarray(guard_frame(jnp.asarray(out), truth, frames[0], nt, mask, guards))
    before = np.asarray(local_wall_plane(jnp.asarray(out), nt, mask)[0])
    after = np.asarray(local_wall_plane(jnp.asarray(got), nt, mask)[0])
    assert (before[rim] > 0.05).all()  # they did cross
    # and are back at the margin of the planes they crossed (re-measured: planes of a few other
    # wall nodes, 0.011-0.030 on this tube)
    assert after[rim].max() < 0.04 and (after[rim] < 0.4 * before[rim]).all()
    np.testing.assert_array_equal(got[deep], out[deep])  # inside: untouched
    np.testing.assert_array_equal(got[nt == NodeType.VESSEL], out[nt == NodeType.VESSEL])
    # a node the truth has as far out (the clot past an open end) is left there
    far = truth.copy()
    far[rim] += 0.2 * radial(truth[rim])
    kept = np.asarray(guard_frame(jnp.asarray(far), far, frames[0], nt, mask, guards))
    np.testing.assert_allclose(kept, far, atol=1e-6)


def test_coherence_pulls_a_deformed_clot_to_within_the_tolerance_of_its_rest_shape():
    frames, nt, mask, rho = _tube()
    clot = np.flatnonzero(nt == NodeType.CLOT)
    deep = clot[rho < 0.5]
    moved = frames[0].copy()
    moved[clot] += [0.0, 0.0, 0.3]  # a rigid move: coherence leaves it
    guards = PushGuards(margin=0.01, tolerance=0.05)
    np.testing.assert_allclose(guard_frame(jnp.asarray(moved), moved, frames[0], nt, mask,
                                           guards), moved, atol=1e-5)
    bent = moved.copy()
    bent[deep[:3]] += [0.0, 0.0, 0.4]  # three inner nodes run ahead of the clot
    got = np.asarray(guard_frame(jnp.asarray(bent), bent, frames[0], nt, mask, guards))
    ahead = got[deep[:3]] - moved[deep[:3]]
    assert np.abs(ahead[:, 2]).max() < 0.1 < 0.4  # pulled most of the way back


def _model_and_window():
    step = tiny_mgn_step()
    frames, nt, mask, _ = _tube(seed=1)
    batch = window_batch([(frames, nt, mask)])
    params = init_state(step, make_optimizer(1e-3), jax.random.PRNGKey(0), batch).params
    return step, params, jnp.asarray(frames), nt, mask


def test_the_loss_starts_from_the_guarded_prediction():
    """p = 1: the loss step reads (s_t, guard(s^_t+1)) and aims at s_t+2; with a tolerance
    of 0 coherence snaps the pushed clot to a rigid copy of its first frame, so the loss is not
    the plain push-forward's."""
    step, params, frames, nt, mask = _model_and_window()
    window, rest = frames[1:5], frames[0]
    guards = PushGuards(margin=0.01, tolerance=0.0)
    clot = nt == NodeType.CLOT

    def manual(pushed):
        out = step(params, _STATS, window[1], pushed, nt, mask)
        target = _STATS.normalize(window[3] - 2 * pushed + window[1])
        return jnp.where(clot[:, None], (out.output - target) ** 2, 0.0).mean(-1).sum()

    raw = step(params, _STATS, window[0], window[1], nt, mask).positions
    pushed = guarded_push(step, params, _STATS, window, rest, nt, mask, 1, guards, train=False,
                          rng=None)[0]
    np.testing.assert_allclose(pushed, guard_frame(raw, window[2], rest, nt, mask, guards),
                               atol=1e-6)
    assert float(jnp.abs(pushed - raw).max()) > 1e-3  # the guards did move the prediction

    def terms(g):
        return window_loss_terms(step, params, _STATS, window, nt, mask, k=1, pushforward=1,
                                 train=False, rng=None, rest=rest, push_guards=g)["loss_sum"]

    np.testing.assert_allclose(terms(guards), manual(pushed), rtol=1e-5)
    np.testing.assert_allclose(terms(None), manual(raw), rtol=1e-5)
    assert abs(float(terms(guards)) - float(terms(None))) > 1e-3 * float(terms(None))
    with pytest.raises(ValueError, match="push-forward guards"):
        window_loss_terms(step, params, _STATS, window, nt, mask, k=1, pushforward=0,
                          train=False, rng=None, rest=rest, push_guards=guards)


def test_batch_loss_reads_the_rest_frame_first_and_refuses_what_it_cannot_guard():
    step, params, frames, nt, mask = _model_and_window()
    guards = PushGuards(margin=0.01, tolerance=0.0)
    led = window_batch([(frames, nt, mask)])  # the rest frame (frame 0) leads the window
    loss, _ = batch_loss(step, params, _STATS, led, None, train=False, pushforward=1,
                         push_guards=guards)
    want = window_loss_terms(step, params, _STATS, frames[1:], nt, mask, k=1, pushforward=1,
                             train=False, rng=None, rest=frames[0], push_guards=guards)
    np.testing.assert_allclose(loss, want["loss_sum"] / want["count"], rtol=1e-5)
    for kwargs in ({"pushforward": 0}, {"pushforward": 1, "flat_batch": True}):
        with pytest.raises(ConfigError, match="push-forward guards"):
            batch_loss(step, params, _STATS, led, None, train=False, push_guards=guards,
                       **kwargs)


def test_input_guards_guard_the_inputs_and_leave_the_targets():
    """In training (no noise here) the loss reads the guarded s_t-1, s_t and aims at the true
    s_t+1: with a tolerance of 0 coherence snaps the deforming clot's inputs to rigid copies."""
    step, params, frames, nt, mask = _model_and_window()
    clot = np.asarray(nt == NodeType.CLOT)
    stretch = 1.0 + 0.1 * np.arange(frames.shape[0], dtype=np.float32)  # the clot lengthens
    frames = frames.at[:, clot, 2].multiply(stretch[:, None])
    guards = PushGuards(margin=0.01, tolerance=0.0)
    window, rest = frames[1:4], frames[0]
    guarded = guard_inputs(window, window, rest, nt, mask, guards, 1)
    np.testing.assert_array_equal(guarded[2], window[2])  # the target frame as it was
    for j in (0, 1):
        np.testing.assert_allclose(guarded[j], guard_frame(window[j], window[j], rest, nt, mask,
                                                           guards), atol=1e-6)
    led = window_batch([(frames[:4], nt, mask)])
    key = jax.random.PRNGKey(0)
    loss, _ = batch_loss(step, params, _STATS, led, key, train=True, input_guards=guards)
    want = window_loss_terms(step, params, _STATS, guarded, nt, mask, train=False, rng=None)
    np.testing.assert_allclose(loss, want["loss_sum"] / want["count"], rtol=1e-5)
    plain = window_loss_terms(step, params, _STATS, window, nt, mask, train=False, rng=None)
    assert abs(float(loss) - float(plain["loss_sum"] / plain["count"])) > 1e-3 * float(loss)
    # evaluation (no key) reads the inputs as they are
    evaluated, _ = batch_loss(step, params, _STATS, led, None, train=False, input_guards=guards)
    np.testing.assert_allclose(evaluated, plain["loss_sum"] / plain["count"], rtol=1e-5)
    with pytest.raises(ConfigError, match="input guards"):
        batch_loss(step, params, _STATS, led, key, train=True, input_guards=guards,
                   flat_batch=True)


def test_config_needs_pushforward_steps_and_the_cli_trains_with_it(tmp_path):
    with pytest.raises(ConfigError, match="--pushforward-steps"):
        TrainConfig(pushforward_guards=True)
    with pytest.raises(ConfigError, match="guard_coherence"):
        TrainConfig(pushforward_guards=True, pushforward_steps=1, guard_coherence=-1.0)
    _, run = train_tiny_cli(tmp_path, "--pushforward-steps", "1", "--pushforward-guards",
                            "--guard-coherence", "0.3", "--noise-std", "0")
    cfg = json.loads((run / "config.json").read_text())["train"]
    assert cfg["pushforward_guards"] is True and cfg["guard_coherence"] == 0.3
    records = [json.loads(x) for x in (run / "metrics.jsonl").read_text().splitlines()]
    assert any(np.isfinite(r.get("train_loss", np.nan)) for r in records)
    _, run = train_tiny_cli(tmp_path / "inputs", "--input-guards")
    cfg = json.loads((run / "config.json").read_text())["train"]
    assert cfg["input_guards"] is True and cfg["guard_coherence"] == 0.2
