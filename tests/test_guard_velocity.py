"""Coherence that keeps the step's velocity (``keep_velocity``): the guard corrects where the
clot is, and the next step still reads the velocity the learned step gave (the previous frame
moves with coherence's correction), in the single, ensemble and committee rollouts."""

import jax
import jax.numpy as jnp
import numpy as np
from wall_factory import straight_tube

from thrombojax.models.registry import create_model, identity_stats
from thrombojax.simulator.committee import committee_rollout
from thrombojax.simulator.ensemble import ensemble_rollout, stack_params
from thrombojax.simulator.guard_set import build_guards
from thrombojax.simulator.rollout import guarded_unroll, rollout_with_corrections
from thrombojax.types import NodeType

N_STEPS = 6


def _stretching_start():
    """A clot in a straight tube whose front moves faster than its rear (0.02-0.06 per step
    along x): at constant velocity it stretches along the tube, inside it."""
    x0, node_type = straight_tube()
    clot = node_type == NodeType.CLOT
    speed = 0.04 + 0.025 * x0[:, 0]  # x0 in [-0.8, 0.8] on the clot
    x_prev = x0 - np.where(clot[:, None], speed[:, None] * [1.0, 0.0, 0.0], 0.0)
    return x_prev.astype(np.float32), x0, node_type, clot


def test_advance_keeps_the_velocity_coherence_took_out():
    x_prev, x0, node_type, clot = _stretching_start()
    nxt = 2 * x0 - x_prev  # the constant-velocity step
    for keep in (False, True):
        guards = build_guards(x0, node_type, x0, node_type, radius=1.0, containment=False,
                              tolerance_r=0.0, keep_velocity=keep)
        prev2, nxt2, corr = jax.jit(lambda p, c, n, g=guards: g.advance(
            lambda a, b: b, p, c, n))(jnp.asarray(x_prev), jnp.asarray(x0), jnp.asarray(nxt))
        prev2, nxt2 = np.asarray(prev2), np.asarray(nxt2)
        assert float(np.asarray(corr["coherence"]).max()) > 1e-3  # the stretch is pulled back
        if keep:
            np.testing.assert_allclose(nxt2 - prev2, nxt - x0, atol=1e-6)
        else:
            np.testing.assert_array_equal(prev2, x0)
        np.testing.assert_array_equal(nxt2[~clot], x0[~clot])


def test_a_kept_velocity_goes_on_stretching_the_clot_into_the_guard():
    """At constant velocity a stretching clot, guarded rigidly: without ``keep_velocity`` the
    first correction takes the stretch out of the velocity too and the guard then has nothing
    left to do; with it the step keeps stretching the clot and the guard corrects it at every
    step. Ensemble members and a committee behave as the single model."""
    x_prev, x0, node_type, clot = _stretching_start()
    model, stats, mask = create_model("constant_velocity"), identity_stats(), np.ones(len(x0), bool)
    stacked = stack_params([{"w": jnp.zeros(1)}, {"w": jnp.zeros(1)}])
    last = {}
    for keep in (False, True):
        guards = build_guards(x0, node_type, x0, node_type, radius=1.0, containment=False,
                              tolerance_r=0.0, keep_velocity=keep)
        traj, corr = rollout_with_corrections(model, {}, stats, x_prev, x0, node_type, mask,
                                              N_STEPS, guards=guards)
        moved = np.asarray(corr["coherence"])[:, clot].max(axis=1)
        last[keep] = moved[-1]
        assert moved[0] > 1e-3
        ens = ensemble_rollout(model, stacked, stats, x_prev, x0, node_type, mask, N_STEPS,
                               rollout_fn=guarded_unroll, context=guards, guard_mean=True)
        com = committee_rollout(model, stacked, stats, x_prev, x0, node_type, mask, N_STEPS,
                                guards=guards)
        np.testing.assert_allclose(np.asarray(ens.mean), np.asarray(traj), atol=1e-5)
        np.testing.assert_allclose(np.asarray(com.mean), np.asarray(traj), atol=1e-5)
    assert last[False] < 1e-4 < 1e-3 < last[True], last


def test_keep_velocity_wall_keeps_the_velocity_containment_took_out():
    """A step that carries the clot's nodes 0.8 away from the tube's axis puts some through the
    wall: containment puts them back either way; with ``keep_velocity_wall`` the next step
    still reads the step's velocity, without it the velocity that containment left."""
    x0, node_type = straight_tube()
    clot = node_type == NodeType.CLOT
    radial = x0 * [0.0, 1.0, 1.0]
    radial /= np.linalg.norm(radial, axis=-1, keepdims=True) + 1e-6
    nxt = np.where(clot[:, None], x0 + 0.8 * radial, x0).astype(np.float32)
    for keep in (False, True):
        guards = build_guards(x0, node_type, x0, node_type, radius=1.0, coherence=False,
                              keep_velocity_wall=keep)
        assert guards.keep_velocity_wall is keep
        prev2, nxt2, corr = jax.jit(lambda p, c, n, g=guards: g.advance(
            lambda a, b: b, p, c, n))(jnp.asarray(x0), jnp.asarray(x0), jnp.asarray(nxt))
        prev2, nxt2 = np.asarray(prev2), np.asarray(nxt2)
        moved = np.asarray(corr["containment"])
        assert (moved[clot] > 1e-3).sum() > 3  # some nodes were put back inside
        assert np.linalg.norm(nxt2[clot] * [0, 1, 1], axis=-1).max() < 1.03  # the wall's slack
        if keep:
            np.testing.assert_allclose(nxt2 - prev2, nxt - x0, atol=1e-6)
        else:
            np.testing.assert_array_equal(prev2, x0)
