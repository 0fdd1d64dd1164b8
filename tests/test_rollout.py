"""Rollout under lax.scan: compiles once, steps are the learned step, rigid vessel, determinism."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from dataset_factory import TRACES, FakeSurrogate, rollout_state

from thrombojax.data.augment import subsample_indices
from thrombojax.errors import ConfigError
from thrombojax.models.registry import create_model, get_config, identity_stats
from thrombojax.simulator.rollout import constant_velocity_rollout, rollout, rollout_jit, unroll
from thrombojax.simulator.step import make_step
from thrombojax.types import NodeType


def _state(n=40, seed=0):
    return rollout_state(n, seed)


def test_rollout_compiles_once_and_each_step_is_the_learned_step():
    model = FakeSurrogate(name="compile-once")  # its own jit cache entry in this process
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

    step = make_step(model)
    first = jax.jit(step)(params, stats, x_prev, x_cur, node_type, mask).positions
    np.testing.assert_allclose(np.asarray(traj[0]), np.asarray(first), rtol=0, atol=1e-6)
    # second step from (s_t, predicted s_{t+1}) matches too: predictions are fed back
    second = step(params, stats, x_cur, first, node_type, mask).positions
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
        idx = subsample_indices(seed, node_type, 24)
        return np.asarray(rollout(model, params, stats, x_prev[idx], x_cur[idx],
                                  node_type[idx], mask[idx], 4))

    assert np.array_equal(run(7), run(7))
    assert not np.array_equal(subsample_indices(7, node_type, 24),
                              subsample_indices(8, node_type, 24))


def test_fixed_subset_keeps_clot_fraction():
    node_type = np.array([NodeType.CLOT] * 250 + [NodeType.VESSEL] * 750)
    idx = subsample_indices(0, node_type, 200)
    assert idx.shape == (200,) and np.unique(idx).size == 200
    assert (node_type[idx] == NodeType.CLOT).sum() == 50
    assert np.array_equal(subsample_indices(0, node_type, 5000), np.arange(1000))
    np.testing.assert_array_equal(idx, subsample_indices(np.random.default_rng(0), node_type, 200))
    with pytest.raises(ConfigError):
        subsample_indices(0, node_type, 0)


def test_constant_velocity_baseline():
    x_prev, x_cur, node_type, mask, stats = _state()
    cv = constant_velocity_rollout(x_prev, x_cur, node_type, mask, 3)
    clot = (node_type == NodeType.CLOT) & mask
    np.testing.assert_allclose(cv[2, clot], x_cur[clot] + 3 * (x_cur - x_prev)[clot], atol=1e-6)
    assert np.array_equal(cv[:, ~clot], np.broadcast_to(x_cur[~clot], cv[:, ~clot].shape))
    model = FakeSurrogate()
    params = model.init(jax.random.key(0), None, None)
    with pytest.raises(ConfigError):
        rollout(model, params, stats, x_prev, x_cur, node_type, mask, 0)


def test_registered_models_first_step_and_baseline():
    x_prev, x_cur, node_type, mask, stats = _state(n=48)
    cv = create_model("constant_velocity")
    traj = rollout(cv, {}, identity_stats(), x_prev, x_cur, node_type, mask, 5)
    np.testing.assert_allclose(np.asarray(traj),
                               constant_velocity_rollout(x_prev, x_cur, node_type, mask, 5),
                               atol=1e-6)
    mgn = create_model("mgn", get_config("mgn", tiny=True))
    step = make_step(mgn)
    params = step.init(jax.random.key(0), x_prev, x_cur, node_type, mask)
    traj = rollout(mgn, params, stats, x_prev, x_cur, node_type, mask, 3)
    first = step(params, stats, x_prev, x_cur, node_type, mask).positions
    np.testing.assert_allclose(np.asarray(traj[0]), np.asarray(first), rtol=0, atol=1e-5)
    fixed = (node_type == NodeType.VESSEL) | ~mask
    assert np.array_equal(np.asarray(traj)[:, fixed],
                          np.broadcast_to(x_cur[fixed], (3, int(fixed.sum()), 3)))


def test_unroll_is_differentiable_through_every_step():
    """Gradients of the last frame reach the parameters through all steps (k-step loss)."""
    model = FakeSurrogate()
    x_prev, x_cur, node_type, mask, stats = _state()
    params = model.init(jax.random.key(0), None, None)
    step = make_step(model)

    def last(p, k):
        return unroll(step, p, stats, x_prev, x_cur, node_type, mask, k)[0][-1].sum()

    g1 = jax.grad(last)(params, 1)
    g3 = jax.grad(last)(params, 3)
    assert all(np.isfinite(np.asarray(x)).all() for x in jax.tree.leaves(g3))
    assert not np.allclose(np.asarray(g1["w"]), np.asarray(g3["w"]))
    # the scan's first output is the single step
    pos, out = unroll(step, params, stats, x_prev, x_cur, node_type, mask, 2)
    single = step(params, stats, x_prev, x_cur, node_type, mask)
    np.testing.assert_allclose(np.asarray(pos[0]), np.asarray(single.positions), atol=1e-6)
    np.testing.assert_allclose(np.asarray(out[0]), np.asarray(single.output), atol=1e-6)
