"""The start span: a start speed measured over the K frames up to the rollout's start
(``make_step(..., start_speed=K)``, ``thrombojax train --start-speed --start-span K``;
:mod:`thrombojax.simulator.start_speed`).

With ``K`` the rollout's start frame the step reads the clot's travel from rest, which tells how
soon the clot broke free; the speed into the start frame alone (``K = 1``) does not."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import ring_clot_window, tiny_mgn_step, train_tiny_step, window_batch
from test_rest_edges import _mgn, _scene
from test_speed_noise import STATS

from thrombojax.errors import ConfigError
from thrombojax.simulator.features import extra_features
from thrombojax.simulator.step import make_step
from thrombojax.types import NodeType


@pytest.mark.parametrize("rest", [False, True])
def test_previous_reads_the_start_frames_k_apart_clipped_at_the_first_frame(rest):
    """``x_prev`` = (rest), s_{c-K}, s_c, s_{t-1} with frames before 0 frame 0; a rollout keeps
    them."""
    pos, nt, _ = _scene(frames=8)
    step = make_step(_mgn(), rest_edges=rest, start_speed=3)
    lead = [pos[0]] if rest else []
    np.testing.assert_array_equal(np.asarray(step.previous(pos, 6)),
                                  np.stack([*lead, pos[3], pos[6], pos[5]]))
    np.testing.assert_array_equal(np.asarray(step.previous(pos, 6, start_from=2)),
                                  np.stack([*lead, pos[0], pos[2], pos[5]]))  # 2 - 3 < 0
    many = np.asarray(step.previous(pos, np.array([1, 7]), start_from=5))
    np.testing.assert_array_equal(many[:, len(lead):len(lead) + 2],
                                  np.stack([pos[[0, 1]], pos[[2, 5]]]))
    prev = step.previous(pos, 5)
    nxt = np.asarray(step.shift(jnp.asarray(prev), jnp.asarray(pos[5])))
    np.testing.assert_array_equal(nxt, np.asarray(step.previous(pos, 6, start_from=5)))
    assert make_step(_mgn(), start_speed=True).previous(pos, 6)[0].tolist() == pos[5].tolist()


def test_batches_read_the_start_frames_k_apart():
    """``make_batch(..., start_speed=(start, H, K))``: frames ``max(c - K, 0), c`` with ``c =
    min(t, start)``; ``(start, H)`` is ``K = 1``."""
    from dataset_factory import numbered_store

    from thrombojax.data.batching import make_batch

    store = numbered_store(9)  # y: the frame number
    times = [store.windows[i][1] for i in range(len(store))]
    entries = np.array([[times.index(2), 0], [times.index(6), 0]])  # frame t = 2 and 6
    one = make_batch(store, entries, 64, nodes_per_sample=20, seed=1, start_speed=(4, 1))
    same = make_batch(store, entries, 64, nodes_per_sample=20, seed=1, start_speed=(4, 1, 1))
    span = make_batch(store, entries, 64, nodes_per_sample=20, seed=1, start_speed=(4, 1, 3))
    np.testing.assert_array_equal(one.frames, same.frames)
    np.testing.assert_array_equal(span.frames[:, 2:], one.frames[:, 2:])
    real = one.mask
    for b, (c0, c1) in enumerate(((0, 2), (1, 4))):
        np.testing.assert_array_equal(span.frames[b, :2, :, 1][:, real[b]],
                                      np.array([[c0], [c1]]) * np.ones((1, real[b].sum())))


def test_the_feature_is_the_mean_speed_over_the_span():
    """The step's start feature is the clot centroid's travel between the two start frames over
    K frames, in units of the velocity scale; K = 1 gives the speed into the start frame."""
    pos, nt, mask = _scene(frames=8)
    clot = (nt == NodeType.CLOT) & mask
    centroid = pos[:, clot].mean(axis=1)
    for k, first in ((1, 4), (3, 2), (9, 0)):
        step = make_step(_mgn(), start_speed=k)
        feat = np.asarray(extra_features(step, None, jnp.asarray(step.previous(pos, 5)),
                                         jnp.asarray(pos[5]), jnp.asarray(nt),
                                         jnp.asarray(mask), 0.5, None))
        want = np.linalg.norm(centroid[5] - centroid[first]) / (0.5 * k)
        np.testing.assert_allclose(feat[clot, -1], want, rtol=1e-4)
        assert not feat[~clot, -1].any()


def _spread_after_training(span: bool) -> float:
    """Train the tiny step on two clots with the same speed into the start frame and the same
    motion before t, one that broke free early (long travel from rest) and speeds up, one that
    broke free late and slows down; return how far apart its two predicted accelerations are,
    over the true difference (1: told apart; 0: one mean for both)."""
    step = make_step(tiny_mgn_step().model, start_speed=3 if span else True)
    windows, accels = [], (0.01, -0.01)
    for travel, accel in ((0.15, accels[0]), (0.06, accels[1])):
        frames, nt, mask = ring_clot_window(0.05, shear=0.01, frames=3, seed=0)
        clot = ((nt == NodeType.CLOT) & mask)[:, None]
        frames = frames.at[2].add(jnp.where(clot, jnp.array([accel, 0.0, 0.0]), 0.0))
        start = frames[0]
        moved = jnp.where(clot, jnp.array([travel if span else 0.05, 0.0, 0.0]), 0.0)
        windows.append((jnp.concatenate([(start - moved)[None], start[None], frames]), nt, mask))
    batch = window_batch(windows)
    params = train_tiny_step(step, batch, STATS, steps=150)
    pred = []
    for f, nt, mask in windows:
        out = step(params, STATS, f[:3], f[3], nt, mask).positions
        clot = (nt == NodeType.CLOT) & mask
        pred.append(float(jnp.mean((out - 2 * f[3] + f[2])[clot, 0])))
    return (pred[0] - pred[1]) / (accels[0] - accels[1])


def test_the_span_tells_apart_clots_that_broke_free_at_different_times():
    """Fails without it: the speed into the start frame is the same for both clots, so a step
    reading it predicts one acceleration for both; over a span from rest it tells them apart."""
    assert abs(_spread_after_training(False)) < 0.2
    assert _spread_after_training(True) > 0.6


def test_the_span_reaches_the_config_cli_and_run_and_needs_the_start_speed(tmp_path):
    from dataset_factory import train_tiny_cli

    from thrombojax.cli import build_parser
    from thrombojax.train.config import TrainConfig
    from thrombojax.train.state import load_trained

    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--start-speed", "--start-span", "4"])
    assert args.start_span == 4
    assert TrainConfig(start_speed=True, start_span=4).start_span == 4
    with pytest.raises(ConfigError, match="--start-span .* needs --start-speed"):
        TrainConfig(start_span=4)
    with pytest.raises(ConfigError, match="start_span"):
        TrainConfig(start_speed=True, start_span=0)
    with pytest.raises(ConfigError, match="start_speed must be an int"):
        make_step(_mgn(), start_speed=-1)
    data, run = train_tiny_cli(tmp_path, "--start-speed", "--start-span", "3", n_nodes=80)
    loaded = load_trained(run)
    assert loaded.run.train.start_span == 3 and loaded.step.start_speed == 3
    frames = jax.numpy.zeros((5, 80, 3))
    assert np.asarray(loaded.step.previous(frames, 4)).shape[0] == 3
