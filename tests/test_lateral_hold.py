"""The lateral hold: the clot-wide mean of the model's acceleration across the vessel's axis is
taken out of the step, so a model cannot push the whole clot sideways; its deformation and its
acceleration along the vessel are kept."""

import jax.numpy as jnp
import numpy as np
import pytest
from test_vessel_axis import _tube

from thrombojax.errors import ConfigError
from thrombojax.graph.vessel_axis import clot_lateral_mean
from thrombojax.models.registry import create_model
from thrombojax.simulator.rollout import unroll
from thrombojax.simulator.step import make_step
from thrombojax.train.loss import window_loss_terms
from thrombojax.types import NodeType, TargetStats

D = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])  # the tube's axis


def _straight(seed=0):
    return _tube(lambda s: s * D, lambda s: D, np.random.default_rng(seed))


def _sideways():
    """A unit vector across the tube."""
    e = np.cross(D, [0.0, 0.0, 1.0])
    return e / np.linalg.norm(e)


def test_the_mean_across_the_axis_goes_and_the_rest_stays():
    x, nt, _ = _straight()
    clot = nt == NodeType.CLOT
    mask = jnp.ones(len(nt), bool)
    rng = np.random.default_rng(1)
    wiggle = rng.normal(0, 0.01, (len(nt), 3))
    wiggle[clot] -= wiggle[clot].mean(axis=0)  # a deformation: zero clot mean
    accel = np.where(clot[:, None], 0.03 * D + 0.02 * _sideways() + wiggle, 0.0)
    held = accel - np.asarray(clot_lateral_mean(jnp.asarray(accel, jnp.float32),
                                                jnp.asarray(x), jnp.asarray(nt), mask,
                                                radius=2.0))
    mean = held[clot].mean(axis=0)
    assert abs(mean @ D - 0.03) < 2e-4  # along the vessel: kept
    assert np.linalg.norm(mean - (mean @ D) * D) < 2e-4  # across: gone (was 0.02)
    spread = held[clot] - mean
    np.testing.assert_allclose(spread, wiggle[clot] - wiggle[clot].mean(axis=0), atol=5e-4)
    assert not held[~clot].any()
    no_vessel = np.full(len(nt), NodeType.CLOT, np.int32)  # no axis: nothing taken out
    assert not np.asarray(clot_lateral_mean(jnp.asarray(accel, jnp.float32), jnp.asarray(x),
                                            jnp.asarray(no_vessel), mask, radius=2.0)).any()


def _pushing_stats():
    """A zero output read as a sideways-and-forward acceleration of every node."""
    return TargetStats(mean=jnp.asarray(0.002 * D + 0.004 * _sideways(), jnp.float32),
                       std=jnp.ones(3, jnp.float32))


def test_a_model_that_pushes_the_clot_sideways_stays_on_the_axis_with_the_hold():
    """Constant velocity whose statistics read every output as a push across the tube: the
    rollout leaves the axis without the hold and follows it with the hold (the push along the
    tube is kept); the loss on a window that moves straight is ~0 with the hold only."""
    x, nt, _ = _straight()
    clot = nt == NodeType.CLOT
    mask = jnp.ones(len(nt), bool)
    v = np.where(clot[:, None], 0.01 * D, 0.0).astype(np.float32)
    cv, stats = create_model("constant_velocity"), _pushing_stats()
    held, free = make_step(cv, lateral_radius=2.0), make_step(cv)
    args = (jnp.asarray(x - v), jnp.asarray(x), jnp.asarray(nt), mask, 10)
    for step, lateral in ((held, 0.0), (free, 10 * 11 / 2 * 0.004)):
        pos, _ = unroll(step, {}, stats, *args, train=False, rng=None)
        moved = np.asarray(pos[-1])[clot].mean(axis=0) - x[clot].mean(axis=0)
        across = moved - (moved @ D) * D
        assert abs(moved @ D - (10 * 0.01 + 10 * 11 / 2 * 0.002)) < 1e-3
        assert abs(np.linalg.norm(across) - lateral) < 1e-3
    truth = np.where(clot[:, None], x + v + 0.002 * D, x).astype(np.float32)
    frames = jnp.asarray(np.stack([x - v, x, truth]))
    kw = dict(train=False, rng=None)
    loss_held, loss_free = (float(window_loss_terms(s, {}, stats, frames, nt, mask, **kw)
                                  ["loss_sum"]) for s in (held, free))
    assert loss_free > 1e-4 and loss_held < 1e-4 * loss_free  # (the axis is estimated)
    with pytest.raises(ConfigError, match="lateral_radius"):
        make_step(cv, lateral_radius=-1.0)
