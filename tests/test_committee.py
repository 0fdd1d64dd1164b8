"""Committee rollouts: M members' mean next frame, guarded, fed back at every step."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import FakeSurrogate, rollout_state

from thrombojax.errors import ConfigError
from thrombojax.simulator.committee import committee_rollout
from thrombojax.simulator.ensemble import ensemble_rollout, stack_params
from thrombojax.simulator.guard_set import build_guards
from thrombojax.simulator.rollout import as_step, rollout
from thrombojax.simulator.walls import fraction_outside_wall
from thrombojax.types import NodeType


def _members(model, seeds):
    return [model.init(jax.random.key(s), None, None) for s in seeds]


def test_one_member_is_the_plain_rollout_with_zero_spread():
    model = FakeSurrogate()
    x_prev, x_cur, node_type, mask, stats = rollout_state()
    (p,) = _members(model, [0])
    com = committee_rollout(model, stack_params([p]), stats, x_prev, x_cur, node_type, mask, 6)
    plain = rollout(model, p, stats, x_prev, x_cur, node_type, mask, 6)
    np.testing.assert_allclose(np.asarray(com.mean), np.asarray(plain), rtol=0, atol=1e-6)
    assert float(jnp.abs(com.spread).max()) == 0.0 and com.mean_corrections is None
    assert com.members.shape == (1, 6, 40, 3)


def test_members_step_together_from_the_mean():
    """Each step is the mean of every member's prediction from the committee's own state (a
    Python loop of the step gives the same frames); the independent ensemble's mean differs."""
    model = FakeSurrogate()
    x_prev, x_cur, node_type, mask, stats = rollout_state()
    params = _members(model, [0, 1, 2])
    com = committee_rollout(model, stack_params(params), stats, x_prev, x_cur, node_type, mask, 5)
    step = as_step(model)
    prev, cur = jnp.asarray(x_prev), jnp.asarray(x_cur)
    for t in range(5):
        preds = np.stack([np.asarray(step(p, stats, prev, cur, node_type, mask).positions)
                          for p in params])
        np.testing.assert_allclose(np.asarray(com.members[:, t]), preds, rtol=0, atol=1e-5)
        mean = preds.mean(axis=0)
        np.testing.assert_allclose(np.asarray(com.mean[t]), mean, rtol=0, atol=1e-5)
        spread = np.sqrt(preds.var(axis=0).mean(axis=-1))
        clot = (node_type == NodeType.CLOT) & mask
        np.testing.assert_allclose(np.asarray(com.spread[t])[clot], spread[clot], atol=1e-5)
        prev, cur = step.shift(prev, cur), jnp.asarray(mean)
    ens = ensemble_rollout(model, stack_params(params), stats, x_prev, x_cur, node_type, mask, 5)
    assert np.abs(np.asarray(ens.mean[-1]) - np.asarray(com.mean[-1])).max() > 1e-4


def test_guards_act_on_the_committee_state():
    """A committee that pushes the clot outward stays inside with guards, leaves without."""
    ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    ring = np.stack([np.zeros_like(ang), np.cos(ang), np.sin(ang)], 1)
    wall = np.concatenate([ring + [x, 0, 0] for x in np.linspace(-2, 2, 21)])
    rng = np.random.default_rng(0)
    clot = rng.uniform(-0.4, 0.4, (30, 3)) * [2.0, 1.0, 1.0]
    x0 = np.concatenate([clot, wall]).astype(np.float32)
    node_type = np.array([NodeType.CLOT] * 30 + [NodeType.VESSEL] * len(wall), np.int32)
    mask = np.ones(len(x0), bool)
    model = FakeSurrogate(radius=0.0)  # no neighbours: the update is velocity + b
    _, _, _, _, stats = rollout_state()
    out = {"w": jnp.zeros((3, 3)), "b": jnp.asarray([0.0, 1.0, 1.0])}  # drift toward y, z > 0
    stack = stack_params([out, {"w": jnp.zeros((3, 3)), "b": 0.5 * out["b"]}])
    guards = build_guards(x0, node_type, x0, node_type, radius=1.0, coherence=False)
    clot_m = jnp.asarray(node_type == NodeType.CLOT)
    free = committee_rollout(model, stack, stats, x0, x0, node_type, mask, 10)
    held = committee_rollout(model, stack, stats, x0, x0, node_type, mask, 10, guards=guards)

    def outside(frames):
        # beyond the containment's tolerance (nodes within it are left where they are)
        return max(float(fraction_outside_wall(f, clot_m, guards.wall, tol=guards.tol))
                   for f in frames)

    assert outside(free.mean) > 0.5 and outside(held.mean) == 0.0
    moved = np.asarray(held.mean_corrections["containment"])
    assert moved.shape == (10, len(x0)) and moved[:, 30:].max() == 0 and moved.max() > 0
    np.testing.assert_array_equal(np.asarray(held.mean)[:, 30:],
                                  np.broadcast_to(x0[30:], (10, *x0[30:].shape)))
    with pytest.raises(ConfigError, match="guards must be a GuardSet"):
        committee_rollout(model, stack, stats, x0, x0, node_type, mask, 3, guards=1.0)
    with pytest.raises(ConfigError, match="committee rollout: n_steps"):
        committee_rollout(model, stack, stats, x0, x0, node_type, mask, 0)
