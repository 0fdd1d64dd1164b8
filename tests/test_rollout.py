"""Rollout under lax.scan: compiles once, first step == predict_next, rigid vessel, determinism."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from thrombojax.errors import CapacityOverflowError, ConfigError
from thrombojax.rollout import (
    constant_velocity_rollout,
    predict_next,
    rollout,
    rollout_jit,
    select_subset,
)
from thrombojax.types import NodeType, TargetStats

TRACES: list[int] = []  # the fake model appends here each time its graph is traced


@dataclasses.dataclass(frozen=True)
class FakeSurrogate:
    """A tiny Surrogate: a dense 'graph' (neighbour mean within r) and a linear update."""

    name: str = "fake"
    radius: float = 0.5
    force_overflow: bool = False

    def build_graph(self, inputs):
        TRACES.append(1)
        d = jnp.linalg.norm(inputs.positions[:, None] - inputs.positions[None], axis=-1)
        adj = (d < self.radius) & inputs.mask[:, None] & inputs.mask[None]
        return {"adj": adj, "overflow": jnp.asarray(self.force_overflow)}

    def init(self, rng, inputs, graph):
        k1, k2 = jax.random.split(rng)
        return {"w": 0.1 * jax.random.normal(k1, (3, 3)), "b": 0.01 * jax.random.normal(k2, (3,))}

    def apply(self, params, inputs, graph, *, train=False, rng=None):
        adj = graph["adj"].astype(jnp.float32)
        nbr_mean = adj @ inputs.positions / jnp.maximum(adj.sum(1, keepdims=True), 1.0)
        return (nbr_mean - inputs.positions) @ params["w"] + inputs.velocity + params["b"]


def _state(n=40, seed=0):
    rng = np.random.default_rng(seed)
    x_cur = rng.uniform(-1, 1, (n, 3)).astype(np.float32)
    x_prev = x_cur - 0.01 * rng.normal(size=(n, 3)).astype(np.float32)
    node_type = np.where(np.arange(n) % 3 == 0, NodeType.CLOT, NodeType.VESSEL).astype(np.int32)
    x_prev[node_type == NodeType.VESSEL] = x_cur[node_type == NodeType.VESSEL]
    mask = np.ones(n, bool)
    mask[-3:] = False
    stats = TargetStats(mean=jnp.full(3, 1e-3), std=jnp.full(3, 0.02))
    return x_prev, x_cur, node_type, mask, stats


def test_rollout_compiles_once_and_first_step_matches_predict_next():
    model = FakeSurrogate()
    x_prev, x_cur, node_type, mask, stats = _state()
    params = model.init(jax.random.key(0), None, None)
    TRACES.clear()
    size0 = rollout_jit._cache_size()
    traj = rollout(model, params, stats, x_prev, x_cur, node_type, mask, 6)
    assert len(TRACES) == 1 and rollout_jit._cache_size() == size0 + 1
    # same shapes, new positions and new parameters: no retrace
    params2 = model.init(jax.random.key(1), None, None)
    traj2 = rollout(model, params2, stats, x_prev + 0.1, x_cur + 0.1, node_type, mask, 6)
    assert len(TRACES) == 1 and rollout_jit._cache_size() == size0 + 1
    assert traj.shape == (6, 40, 3) and not np.allclose(traj, traj2)

    first, _ = jax.jit(predict_next, static_argnums=0)(
        model, params, stats, x_prev, x_cur, node_type, mask
    )
    np.testing.assert_allclose(np.asarray(traj[0]), np.asarray(first), rtol=0, atol=1e-6)
    # second step from (s_t, predicted s_{t+1}) matches too
    second, _ = predict_next(model, params, stats, x_cur, first, node_type, mask)
    np.testing.assert_allclose(np.asarray(traj[1]), np.asarray(second), rtol=0, atol=1e-5)


def test_vessel_and_padding_exactly_fixed_and_deterministic():
    model = FakeSurrogate()
    x_prev, x_cur, node_type, mask, stats = _state()
    params = model.init(jax.random.key(0), None, None)
    traj = np.asarray(rollout(model, params, stats, x_prev, x_cur, node_type, mask, 8))
    fixed = (node_type == NodeType.VESSEL) | ~mask
    assert np.array_equal(traj[:, fixed], np.broadcast_to(x_cur[fixed], traj[:, fixed].shape))
    assert np.abs(traj[-1, ~fixed] - x_cur[~fixed]).max() > 1e-3  # clot moved
    again = np.asarray(rollout(model, params, stats, x_prev, x_cur, node_type, mask, 8))
    assert np.array_equal(traj, again)


def test_same_seed_same_subset_rollout():
    model = FakeSurrogate()
    x_prev, x_cur, node_type, mask, stats = _state(n=60, seed=3)
    params = model.init(jax.random.key(0), None, None)

    def run(seed):
        idx = select_subset(node_type, 24, seed=seed)
        return np.asarray(rollout(model, params, stats, x_prev[idx], x_cur[idx],
                                  node_type[idx], mask[idx], 4))

    assert np.array_equal(run(7), run(7))
    assert not np.array_equal(select_subset(node_type, 24, seed=7),
                              select_subset(node_type, 24, seed=8))


def test_select_subset_keeps_clot_fraction():
    node_type = np.array([NodeType.CLOT] * 250 + [NodeType.VESSEL] * 750)
    idx = select_subset(node_type, 200, seed=0)
    assert idx.shape == (200,) and np.unique(idx).size == 200
    assert (node_type[idx] == NodeType.CLOT).sum() == 50
    assert np.array_equal(select_subset(node_type, 5000), np.arange(1000))
    with pytest.raises(ConfigError):
        select_subset(node_type, 0)


def test_constant_velocity_baseline_and_overflow_flag():
    x_prev, x_cur, node_type, mask, stats = _state()
    cv = constant_velocity_rollout(x_prev, x_cur, node_type, mask, 3)
    clot = (node_type == NodeType.CLOT) & mask
    np.testing.assert_allclose(cv[2, clot], x_cur[clot] + 3 * (x_cur - x_prev)[clot], atol=1e-6)
    assert np.array_equal(cv[:, ~clot], np.broadcast_to(x_cur[~clot], cv[:, ~clot].shape))
    model = FakeSurrogate(force_overflow=True)
    params = model.init(jax.random.key(0), None, None)
    with pytest.raises(CapacityOverflowError, match="step 1"):
        rollout(model, params, stats, x_prev, x_cur, node_type, mask, 2)
    with pytest.raises(ConfigError):
        rollout(model, params, stats, x_prev, x_cur, node_type, mask, 0)


def test_registered_models_first_step_and_baseline():
    from thrombojax.models.registry import create_model, get_config, identity_stats

    x_prev, x_cur, node_type, mask, stats = _state(n=48)
    cv = create_model("constant_velocity")
    traj = rollout(cv, {}, identity_stats(), x_prev, x_cur, node_type, mask, 5)
    np.testing.assert_allclose(np.asarray(traj),
                               constant_velocity_rollout(x_prev, x_cur, node_type, mask, 5),
                               atol=1e-6)
    mgn = create_model("mgn", get_config("mgn", tiny=True))
    from thrombojax.rollout import make_input

    inputs = make_input(x_prev, x_cur, node_type, mask)
    params = mgn.init(jax.random.key(0), inputs, mgn.build_graph(inputs))
    traj = rollout(mgn, params, stats, x_prev, x_cur, node_type, mask, 3)
    first, _ = predict_next(mgn, params, stats, x_prev, x_cur, node_type, mask)
    np.testing.assert_allclose(np.asarray(traj[0]), np.asarray(first), rtol=0, atol=1e-5)
    fixed = (node_type == NodeType.VESSEL) | ~mask
    assert np.array_equal(np.asarray(traj)[:, fixed],
                          np.broadcast_to(x_cur[fixed], (3, int(fixed.sum()), 3)))
