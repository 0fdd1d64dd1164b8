"""Training noise with a share common to the whole clot (``noise_shared``).

Independent per-node noise is averaged away by message passing; a rollout's error is a
clot-wide drift. ``shared`` mixes one Gaussian vector per window, the same on every clot node,
into the per-node draw so each node keeps the std ``std`` and that share of its variance is
common to the clot (:mod:`thrombojax.train.noise`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import synthetic_window

from thrombojax.data.batching import Batch
from thrombojax.errors import ConfigError
from thrombojax.train.config import TrainConfig
from thrombojax.train.noise import add_training_noise
from thrombojax.train.step import batch_loss
from thrombojax.types import NodeType, TargetStats

N_KEYS = 3000


def _cloud(n=64, frames=4):
    nt = np.full(n, NodeType.CLOT, np.int32)
    nt[:8] = NodeType.VESSEL
    mask = np.ones(n, bool)
    mask[-4:] = False  # padding
    traj = np.zeros((frames, n, 3), np.float32)
    return jnp.asarray(traj), jnp.asarray(nt), jnp.asarray(mask)


def _noise(shared, current=1, walk=False, std=0.1, gamma=0.25):
    traj, nt, mask = _cloud(frames=current + 2)
    keys = jax.random.split(jax.random.key(0), N_KEYS)
    draw = jax.vmap(lambda k: add_training_noise(k, traj, nt, mask, std=std, gamma=gamma,
                                                 current=current, walk=walk, shared=shared))
    return np.asarray(draw(keys)), np.asarray(nt), np.asarray(mask)


def _shared_fraction(noise, clot):
    """Share of the per-node variance common to the clot: var(clot mean) / var(one node)."""
    per_node = noise[:, clot].var()
    common = noise[:, clot].mean(axis=1).var()
    return common / per_node, np.sqrt(per_node)


@pytest.mark.parametrize("shared", [0.0, 0.3, 0.8])
def test_a_share_of_the_noise_is_common_to_the_clot(shared):
    """Fails without the shared part: the clot-mean of independent noise has a variance of
    1 / n_clot of a node's."""
    noisy, nt, mask = _noise(shared)
    clot = (nt == NodeType.CLOT) & mask
    n = noisy[:, 1]
    fraction, node_std = _shared_fraction(n, clot)
    n_clot = clot.sum()
    expect = shared + (1.0 - shared) / n_clot
    assert abs(fraction - expect) < 0.06, (fraction, expect)
    assert abs(node_std - 0.1) < 0.004  # each node keeps the std
    assert np.all(n[:, ~clot] == 0.0)  # vessel and padding untouched
    np.testing.assert_array_equal(noisy[:, 0], 0.0)  # s_{t-1} exact
    np.testing.assert_allclose(noisy[:, 2], 0.75 * n, atol=1e-6)  # target moved by (1 - gamma)


def test_no_share_is_the_plain_draw_of_earlier_versions():
    traj, nt, mask = _cloud()
    key = jax.random.key(3)
    noisy = np.asarray(add_training_noise(key, traj, nt, mask, std=0.1, shared=0.0))
    clot = np.asarray((nt == NodeType.CLOT) & mask)[:, None]
    plain = np.where(clot, 0.1 * np.asarray(jax.random.normal(key, traj.shape[1:])), 0.0)
    np.testing.assert_array_equal(noisy[1], plain)


def test_the_random_walk_over_a_history_shares_the_same_fraction():
    noisy, nt, mask = _noise(0.6, current=2, walk=True)
    clot = (nt == NodeType.CLOT) & mask
    for frame in (1, 2):  # s_{t-1} and s_t, both corrupted by the walk
        fraction, _ = _shared_fraction(noisy[:, frame], clot)
        assert abs(fraction - (0.6 + 0.4 / clot.sum())) < 0.06, (frame, fraction)
    np.testing.assert_array_equal(noisy[:, 0], 0.0)


def test_bad_shares_are_refused_by_name():
    traj, nt, mask = _cloud()
    with pytest.raises(ValueError, match="shared"):
        add_training_noise(jax.random.key(0), traj, nt, mask, std=0.1, shared=1.5)
    for bad in (1.5, -0.1):
        with pytest.raises(ConfigError, match="noise_shared"):
            TrainConfig(noise_shared=bad)
    from thrombojax.cli import build_parser

    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--noise-shared", "0.5"])
    assert args.noise_shared == 0.5


def test_the_training_loss_uses_the_share():
    """The option reaches the loss: same key, other share, other noisy windows."""
    from thrombojax.models.registry import create_model, get_config
    from thrombojax.simulator.step import make_step

    frames, nt, mask = synthetic_window()
    batch = Batch(frames=np.stack([frames, frames]), node_type=np.stack([nt, nt]),
                  mask=np.stack([mask, mask]), generated=np.zeros(2, bool))
    stats = TargetStats(mean=jnp.zeros(3), std=jnp.full(3, 0.01), velocity_std=jnp.asarray(0.02))
    step = make_step(create_model("mgn", get_config("mgn", tiny=True, max_neighbors=6)))
    params = step.init(jax.random.key(0), frames[0], frames[1], nt, mask)
    losses = [float(batch_loss(step, params, stats, batch, jax.random.key(1), train=True,
                               noise_std=0.01, noise_shared=s)[0]) for s in (0.0, 0.0, 0.9)]
    assert losses[0] == losses[1] != losses[2]
