"""Wall noise: clot nodes near the wall moved through it, the targets by half as much.

A rollout leaves the vessel through states the data never shows; the wall noise
(:func:`thrombojax.train.noise.add_wall_noise`) shows them, with the next frame moved by only
half the crossing, so the model learns to bring a node that crossed the wall back. The wall
comes from the frame alone (:func:`thrombojax.graph.wall_nodes.local_wall_plane`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from thrombojax.data.batching import Batch
from thrombojax.errors import ConfigError
from thrombojax.graph.wall_nodes import local_wall_plane, signed_wall_features, wall_node_features
from thrombojax.train.config import TrainConfig
from thrombojax.train.noise import add_wall_noise
from thrombojax.types import NodeType, TargetStats

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)

STD = 0.1


def _tube(n_clot=96, n_pad=6, seed=0):
    """A straight tube of radius 1 along z (vessel rings) and a clot inside it, some of its
    nodes touching the wall; returns ``(x [N, 3], node_type, mask, clot radius [n_clot])``."""
    rng = np.random.default_rng(seed)
    ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    rings = np.linspace(-2.0, 2.0, 21)
    vessel = np.array([[np.cos(a), np.sin(a), z] for z in rings for a in ang])
    rho = np.concatenate([rng.uniform(0.0, 0.7, n_clot // 2),
                          rng.uniform(0.93, 0.99, n_clot - n_clot // 2)])
    phi = rng.uniform(0, 2 * np.pi, n_clot)
    clot = np.stack([rho * np.cos(phi), rho * np.sin(phi), rng.uniform(-1.0, 1.0, n_clot)], 1)
    x = np.concatenate([vessel, clot, np.zeros((n_pad, 3))]).astype(np.float32)
    nt = np.array([NodeType.VESSEL] * len(vessel) + [NodeType.CLOT] * n_clot
                  + [NodeType.VESSEL] * n_pad, np.int32)
    mask = np.arange(len(x)) < len(vessel) + n_clot
    return x, nt, mask, rho


def _radial(x):
    r = np.linalg.norm(x[:, :2], axis=1)
    return r, np.stack([x[:, 0] / r, x[:, 1] / r, np.zeros(len(x))], 1)


def test_local_wall_plane_is_the_signed_distance_to_a_tube():
    x, nt, mask, _ = _tube()
    signed, normal = map(np.asarray, local_wall_plane(jnp.asarray(x), nt, mask))
    clot = (nt == NodeType.CLOT) & mask
    r, radial = _radial(x[clot])
    near = r > 0.5  # deep inside, the nearest wall nodes' normals spread around the axis
    # the polygon of 24 nodes lies inside the circle by at most 1 - cos(pi / 24) = 0.009
    assert np.abs(signed[clot][near] - (r[near] - 1.0)).max() < 0.02
    assert (np.sum(normal[clot][near] * radial[near], axis=1) > 0.98).all()
    # a node through the wall reads positive, with the same outward normal
    out = x.copy()
    i = np.flatnonzero(clot)[-1]
    out[i, :2] *= 1.2 / np.linalg.norm(out[i, :2])
    s_out, n_out = map(np.asarray, local_wall_plane(jnp.asarray(out), nt, mask))
    assert 0.18 < s_out[i] < 0.22
    assert np.dot(n_out[i], _radial(out[i:i + 1])[1][0]) > 0.98


def test_local_wall_plane_without_a_wall_is_zero():
    x, nt, mask, _ = _tube()
    no_vessel = mask & (nt == NodeType.CLOT)
    signed, normal = local_wall_plane(jnp.asarray(x), nt, no_vessel)
    assert not np.asarray(signed).any() and not np.asarray(normal).any()
    with pytest.raises(ValueError, match="k_normal"):
        local_wall_plane(jnp.asarray(x), nt, mask, k_normal=2)


def _window(frames=4):
    x, nt, mask, rho = _tube()
    return jnp.asarray(np.repeat(x[None], frames, axis=0)), nt, mask, rho


def test_wall_noise_moves_half_the_near_wall_nodes_through_the_wall():
    frames, nt, mask, rho = _window()
    keys = jax.random.split(jax.random.key(0), 200)
    noisy = np.asarray(jax.jit(jax.vmap(lambda k: add_wall_noise(k, frames, nt, mask, std=STD)))(
        keys))
    f = np.asarray(frames)
    move = noisy - f[None]  # [keys, W, N, 3]
    # the input frames (s_{t-1}, s_t: current = 1) move alike, the targets by half of it
    np.testing.assert_allclose(move[:, 0], move[:, 1], atol=1e-6)
    for w in (2, 3):
        np.testing.assert_allclose(move[:, w], 0.5 * move[:, 1], atol=1e-6)
    moved = np.linalg.norm(move[:, 1], axis=-1) > 0  # [keys, N]
    clot = np.flatnonzero((nt == NodeType.CLOT) & mask)
    assert not moved[:, np.setdiff1d(np.arange(len(nt)), clot)].any()  # vessel, padding
    near = rho > 1.0 - STD  # the candidates: within std of the wall
    assert not moved[:, clot[~near]].any()
    assert 0.45 < moved[:, clot[near]].mean() < 0.55
    # every moved node ends outside the tube, along the radial direction
    r_after = np.linalg.norm(noisy[:, 1, :, :2], axis=-1)
    assert (r_after[moved] > 1.0).all()
    assert np.median(r_after[moved] - 1.0) > 0.5 * STD  # depth ~ STD |z|: median 0.67 STD
    drift_z = np.abs(move[:, 1, :, 2])[moved]
    assert drift_z.max() < 0.02  # the move is normal to the wall
    # gamma = 1: the targets stay; gamma = 0: they move with the inputs
    for gamma, share in ((1.0, 0.0), (0.0, 1.0)):
        g = np.asarray(add_wall_noise(keys[0], frames, nt, mask, std=STD, gamma=gamma)) - f
        np.testing.assert_allclose(g[2], share * g[1], atol=1e-6)


def test_wall_noise_off_and_bad_values():
    frames, nt, mask, _ = _window()
    assert add_wall_noise(jax.random.key(0), frames, nt, mask, std=0.0) is frames
    with pytest.raises(ValueError, match="wall noise"):
        add_wall_noise(jax.random.key(0), frames, nt, mask, std=-0.1)
    with pytest.raises(ValueError, match="gamma"):
        add_wall_noise(jax.random.key(0), frames, nt, mask, std=0.1, gamma=1.5)
    with pytest.raises(ConfigError, match="wall_noise"):
        TrainConfig(wall_noise=-0.1)
    from thrombojax.cli import build_parser

    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--wall-noise", "0.1"])
    assert args.wall_noise == 0.1


def _resting_batch(size=2):
    frames, nt, mask, _ = _window(frames=3)
    f = np.asarray(frames)
    return Batch(frames=np.stack([f] * size), node_type=np.stack([nt] * size),
                 mask=np.stack([mask] * size), generated=np.zeros(size, bool))


def _tiny_step(features: str = "none"):
    """The tiny MeshGraphNet's step with no wall features, the nearest-vessel-node ones or the
    signed ones (cut off at 0.3)."""
    from thrombojax.models.registry import create_model, get_config
    from thrombojax.simulator.step import make_step

    model = create_model("mgn", get_config("mgn", tiny=True, max_neighbors=8, radius=0.45))
    return make_step(model, wall_cutoff=0.0 if features == "none" else 0.3,
                     wall_signed=features == "signed")


STATS = TargetStats(mean=jnp.zeros(3), std=jnp.full(3, 0.05), velocity_std=jnp.asarray(0.05))


def test_the_training_loss_uses_the_wall_noise():
    from thrombojax.train.step import batch_loss

    batch, step = _resting_batch(), _tiny_step()
    params = step.init(jax.random.key(0), batch.frames[0, 0], batch.frames[0, 1],
                       batch.node_type[0], batch.mask[0])
    loss = jax.jit(lambda p, w: batch_loss(step, p, STATS, batch, jax.random.key(1), train=True,
                                           wall_noise=w)[0], static_argnums=1)
    losses = [float(loss(params, w)) for w in (0.0, 0.0, STD)]
    assert losses[0] == losses[1] != losses[2]


def _inward_after_training(wall_noise: float, features: str) -> float:
    """Train the tiny model on a clot at rest (every target 0) with or without wall noise, then
    put the near-wall clot nodes 0.1 outside the wall in both input frames (at rest there, as a
    node a rollout carried out) and return the mean inward acceleration it predicts for them."""
    from thrombojax.train.schedule import make_optimizer
    from thrombojax.train.step import init_state, make_train_step

    batch, step = _resting_batch(), _tiny_step(features)
    tx = make_optimizer(3e-3)
    state = init_state(step, tx, jax.random.key(0), batch)
    train_step = make_train_step(step, tx, STATS, wall_noise=wall_noise, donate=False)
    for i in range(150):
        state, _ = train_step(state, batch, jax.random.key(i))
    frames, nt, mask, rho = _window(frames=2)
    clot = np.flatnonzero((nt == NodeType.CLOT) & mask)
    out = clot[rho > 0.95]
    x = np.asarray(frames[1]).copy()
    _, radial = _radial(x[out])
    x[out] += 0.1 * radial
    pred = step(state.params, STATS, jnp.asarray(x), jnp.asarray(x), nt, mask).positions
    accel = np.asarray(pred)[out] - x[out]
    return float(-np.mean(np.sum(accel * radial, axis=1)))


def test_wall_noise_with_signed_wall_features_teaches_a_model_to_bring_crossed_nodes_back():
    """Fails without either part. The target is half the crossing (0.05) per step. Without the
    wall noise the model never sees a crossed node and leaves it where it is; without the signed
    features a node at rest outside the wall looks like one at rest inside it (the nearest
    vessel node is as near), so the model cannot learn which to move (measured: 0.007)."""
    learned = _inward_after_training(STD, "signed")
    assert learned > 0.025
    assert _inward_after_training(0.0, "signed") < 0.01
    assert _inward_after_training(STD, "nearest") < 0.5 * learned


def test_signed_wall_features_tell_outside_from_inside():
    x, nt, mask, _ = _tube()
    clot = np.flatnonzero((nt == NodeType.CLOT) & mask)
    i = clot[-1]
    inside, outside = x.copy(), x.copy()
    inside[i, :2] *= 0.95 / np.linalg.norm(x[i, :2])
    outside[i, :2] *= 1.05 / np.linalg.norm(x[i, :2])
    signed = [np.asarray(signed_wall_features(jnp.asarray(p), nt, mask, cutoff=0.3))[i]
              for p in (inside, outside)]
    nearest = [np.asarray(wall_node_features(jnp.asarray(p), nt, mask, cutoff=0.3))[i]
               for p in (inside, outside)]
    # +- 0.05, within the 24-gon's chord depth (<= 0.009, i.e. 0.03 of the cutoff)
    np.testing.assert_allclose(signed[0][0], -0.05 / 0.3, atol=0.03)
    np.testing.assert_allclose(signed[1][0], 0.05 / 0.3, atol=0.03)
    np.testing.assert_allclose(signed[0][1:], signed[1][1:], atol=1e-3)  # the outward normal
    assert abs(nearest[0][0] - nearest[1][0]) < 0.1  # the nearest-node distance barely differs
    feats = np.asarray(signed_wall_features(jnp.asarray(x), nt, mask, cutoff=0.3))
    assert not feats[~((nt == NodeType.CLOT) & mask)].any()
    with pytest.raises(ConfigError, match="wall-signed"):
        TrainConfig(wall_signed=True)
    with pytest.raises(ValueError, match="dense search"):
        local_wall_plane(jnp.zeros((9000, 3)), jnp.zeros(9000, jnp.int32), jnp.ones(9000, bool))


def test_cli_trains_with_wall_noise_and_signed_features_and_rollouts_read_them(tmp_path):
    """`thrombojax train --wall-noise --wall-features --wall-signed`: the run records both, the
    loaded step computes the signed features, and a rollout runs through it."""
    import json

    from dataset_factory import train_tiny_cli

    from thrombojax.eval.report import rollout_run
    from thrombojax.train.state import load_trained

    data, run = train_tiny_cli(tmp_path, "--wall-noise", "0.1", "--wall-features", "0.5",
                               "--wall-signed")
    loaded = load_trained(run)
    assert loaded.run.train.wall_noise == 0.1 and loaded.run.train.wall_signed
    assert loaded.step.wall_signed and loaded.step.wall_cutoff > 0
    report = rollout_run(run, data, tmp_path / "rollout", progress=False, gif=False)
    sims = report["simulations"]
    assert sims and all("NaN" not in json.dumps(r["summary"]) for r in sims.values())
