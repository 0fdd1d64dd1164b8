"""Rotation ensembles: one model on M rotated copies of a simulation, turned back and averaged."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import FakeSurrogate, accelerating_sims, rollout_state

from thrombojax.errors import ConfigError
from thrombojax.models.registry import create_model, identity_stats
from thrombojax.simulator.rollout import rollout
from thrombojax.simulator.rotations import (
    RotatedStep,
    fixed_rotations,
    rotated_params,
    rotation_rollout,
)
from thrombojax.simulator.step import make_step
from thrombojax.types import NodeType, TargetStats


def _setup(seed=0):
    model = FakeSurrogate()
    x_prev, x_cur, node_type, mask, stats = rollout_state(40, seed)
    return model, model.init(jax.random.key(seed), None, None), (x_prev, x_cur, node_type, mask,
                                                                  stats)


def test_fixed_rotations_are_rotations_identity_first_and_repeatable():
    rots = fixed_rotations(6, seed=3)
    assert rots.shape == (6, 3, 3) and rots.dtype == np.float32
    assert np.array_equal(rots[0], np.eye(3, dtype=np.float32))
    np.testing.assert_allclose(rots @ np.swapaxes(rots, 1, 2), np.broadcast_to(np.eye(3),
                                                                               (6, 3, 3)),
                               atol=1e-6)
    np.testing.assert_allclose(np.linalg.det(rots), 1.0, atol=1e-6)
    assert np.array_equal(rots, fixed_rotations(6, seed=3))
    assert not np.allclose(rots[1:], fixed_rotations(6, seed=4)[1:])
    for bad in (0, -1, 2.5, True):
        with pytest.raises(ConfigError, match="n >= 1"):
            fixed_rotations(bad)


def test_rotated_params_refuse_matrices_that_are_not_rotations():
    with pytest.raises(ConfigError, match=r"\[M, 3, 3\]"):
        rotated_params({"w": jnp.ones(3)}, np.eye(3))
    mirror = np.diag([1.0, 1.0, -1.0])[None]
    with pytest.raises(ConfigError, match="rotation"):
        rotated_params({"w": jnp.ones(3)}, mirror)
    with pytest.raises(ConfigError, match="rotation"):
        rotated_params({"w": jnp.ones(3)}, 2 * np.eye(3)[None])


def test_identity_alone_is_the_plain_rollout_to_rounding():
    """One unturned copy is the plain rollout: to float32 rounding, as the two are different
    compiled programs (XLA may fuse and round them differently; 6e-8 of positions about 1 with
    the older CPU emitters the suite compiles with, tests/conftest.py), and with no spread."""
    model, params, (x_prev, x_cur, node_type, mask, stats) = _setup()
    plain = np.asarray(rollout(model, params, stats, x_prev, x_cur, node_type, mask, 6))
    ens = rotation_rollout(model, params, stats, x_prev, x_cur, node_type, mask, 6,
                           rotations=fixed_rotations(1))
    np.testing.assert_allclose(np.asarray(ens.mean), plain, rtol=0, atol=1e-6)
    assert np.array_equal(np.asarray(ens.spread), np.zeros((6, 40)))


def test_member_is_the_rollout_of_the_turned_simulation_turned_back():
    model, params, (x_prev, x_cur, node_type, mask, stats) = _setup(1)
    rots = fixed_rotations(3, seed=1)
    ens = rotation_rollout(model, params, stats, x_prev, x_cur, node_type, mask, 5,
                           rotations=rots)
    members = np.asarray(ens.members)
    assert members.shape == (3, 5, 40, 3)
    for i, rot in enumerate(rots):
        turned = np.asarray(rollout(model, params, stats, x_prev @ rot.T, x_cur @ rot.T,
                                    node_type, mask, 5))
        np.testing.assert_allclose(members[i], turned @ rot, rtol=0, atol=2e-5)
    assert not np.allclose(members[1], members[0], atol=1e-4)  # the fake model is not equivariant
    np.testing.assert_allclose(np.asarray(ens.mean), members.mean(0), atol=1e-6)
    rigid = (node_type != NodeType.CLOT) | ~mask  # vessel and padding never move, in any member
    assert np.array_equal(members[:, :, rigid], np.broadcast_to(x_cur[rigid], (3, 5,
                                                                               rigid.sum(), 3)))


def test_an_equivariant_step_has_no_spread_and_a_global_bias_averages_out():
    x_prev, x_cur, node_type, mask, _ = rollout_state(40, 2)
    clot = (node_type == NodeType.CLOT) & mask
    cv = make_step(create_model("constant_velocity"))  # exactly equivariant
    ens = rotation_rollout(cv, {}, identity_stats(), x_prev, x_cur, node_type, mask, 4,
                           rotations=8)
    assert float(np.asarray(ens.spread).max()) < 1e-5
    # a model that pushes every clot node along the global +x: a rotation ensemble of it
    # pushes along no direction in particular, so its mean drifts far less than one copy
    push = make_step(create_model("constant_velocity"))
    stats = TargetStats(mean=jnp.asarray([0.01, 0.0, 0.0]), std=jnp.ones(3))
    single = np.asarray(rollout(push, {}, stats, x_prev, x_cur, node_type, mask, 5))
    base = np.asarray(rollout(cv, {}, identity_stats(), x_prev, x_cur, node_type, mask, 5))
    many = rotation_rollout(push, {}, stats, x_prev, x_cur, node_type, mask, 5, rotations=64)
    drift_single = np.linalg.norm(single[-1, clot] - base[-1, clot], axis=-1).mean()
    drift_many = np.linalg.norm(np.asarray(many.mean)[-1, clot] - base[-1, clot], axis=-1).mean()
    assert drift_single == pytest.approx(0.15, rel=1e-3)  # 0.01 (1 + 2 + ... + 5)
    assert drift_many < 0.25 * drift_single


def test_init_and_equality():
    model, _, (x_prev, x_cur, node_type, mask, _) = _setup()
    step = make_step(model)
    rotated = RotatedStep.of(step)
    assert RotatedStep.of(rotated) is rotated
    assert rotated != step  # a static argument of jit: its own compilations
    params = rotated.init(jax.random.key(0), x_prev, x_cur, node_type, mask)
    assert np.array_equal(np.asarray(params["rotation"]), np.eye(3))
    plain = step.init(jax.random.key(0), x_prev, x_cur, node_type, mask)
    assert jax.tree.structure(params["inner"]) == jax.tree.structure(plain)


def test_guards_keep_every_turned_member_and_the_mean_inside():
    from wall_factory import Outward, straight_tube

    from thrombojax.simulator.guard_set import build_guards
    from thrombojax.simulator.rollout import guarded_unroll
    from thrombojax.simulator.walls import fraction_outside_wall

    x0, node_type = straight_tube(half_length=3.0, n_rings=31)  # no clot node reaches an end
    wall = x0[30:]
    mask = np.ones(len(x0), bool)
    stats = TargetStats(mean=jnp.zeros(3), std=jnp.ones(3))
    guards = build_guards(x0, node_type, x0, node_type, radius=1.0, coherence=False)
    inside = jnp.asarray(node_type == NodeType.CLOT)

    share = jax.jit(jax.vmap(lambda f: fraction_outside_wall(f, inside, guards.wall)))

    def worst(frames):
        return float(share(jnp.asarray(frames).reshape(-1, *x0.shape)).max())

    # 6 steps: no clot node reaches an open end (it moves at most 0.05 (1 + ... + 6) = 1.05)
    push = Outward(name="outward_turned")
    free = rotation_rollout(push, {}, stats, x0, x0, node_type, mask, 6, rotations=4)
    held = rotation_rollout(push, {}, stats, x0, x0, node_type, mask, 6, rotations=4,
                            rollout_fn=guarded_unroll, context=guards, guard_mean=True)
    # pushes away from the x axis of its inputs: the vessel's only in the unturned copy
    assert worst(free.members) > 0.5
    assert worst(held.members) == 0.0 and worst(held.mean) == 0.0
    assert float(np.asarray(held.aux["containment"]).max()) > 0.0  # per member, per step
    np.testing.assert_array_equal(np.asarray(held.members)[:, :, 30:],
                                  np.broadcast_to(x0[30:], (4, 6, len(wall), 3)))


def test_a_real_model_single_step_through_the_rotated_step():
    from thrombojax.eval.single_step import ensemble_single_step_errors, single_step_errors
    from thrombojax.models.registry import get_config

    sim = accelerating_sims(n_sims=1, n_nodes=64, n_frames=7)[0]
    pos = np.asarray(sim.positions, np.float32) / 10.0
    nt = np.asarray(sim.node_type, np.int32)
    step = make_step(create_model("mgn", get_config("mgn", tiny=True)))
    params = step.init(jax.random.key(0), pos[0], pos[1], nt, np.ones(len(nt), bool))
    stats = TargetStats(mean=np.zeros(3, np.float32), std=np.full(3, 0.05, np.float32),
                        velocity_std=np.float32(0.01))
    plain = single_step_errors(step, params, stats, pos, nt, batch_size=3)
    rotated = RotatedStep.of(step)
    rots = fixed_rotations(3)
    alone = ensemble_single_step_errors(rotated, [{"inner": params, "rotation": rots[0]}],
                                        stats, pos, nt, batch_size=3)
    np.testing.assert_allclose(alone, plain, rtol=1e-6, atol=0)
    three = ensemble_single_step_errors(rotated, [{"inner": params, "rotation": r}
                                                  for r in rots], stats, pos, nt, batch_size=3)
    assert three.shape == plain.shape and np.isfinite(three).all()
    assert not np.allclose(three, plain)  # an untrained MGN is not equivariant
