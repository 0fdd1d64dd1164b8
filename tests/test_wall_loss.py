"""The wall term of the loss (``wall_loss_weight``): zero on the truth and inside the wall, the
squared outward excess beyond the truth's, a gradient along the wall's normal, and the same
training steps take a model's crossing of the wall out faster with it than without it."""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from dataset_factory import radial, tube_window, window_batch

from thrombojax.errors import ConfigError
from thrombojax.graph.wall_nodes import local_wall_plane
from thrombojax.models.registry import create_model, get_config
from thrombojax.simulator.step import make_step
from thrombojax.train.checks import check_dense_inputs
from thrombojax.train.config import TrainConfig
from thrombojax.train.loss import window_loss_terms
from thrombojax.train.schedule import make_optimizer
from thrombojax.train.step import batch_loss, init_state, make_train_step
from thrombojax.train.wall_loss import wall_excess, wall_sum
from thrombojax.types import NodeType, TargetStats

_STATS = TargetStats(mean=jnp.zeros(3), std=jnp.array([0.01, 0.02, 0.02]), velocity_std=0.02)
_SIGMA = float(np.sqrt(np.mean(np.square([0.01, 0.02, 0.02]))))


def _tube_window(seed=0, n_clot=40, n_pad=4, speed=0.05, touch=(0.95, 0.99)):
    """Three frames of a clot sliding along z inside a straight tube of radius 1 (24 x 13 wall
    nodes), half of its nodes against the wall (radius in ``touch``); ``(frames, nt, mask,
    rho)``."""
    return tube_window(seed, n_clot, n_pad, speed, touch)


def test_the_excess_is_zero_on_the_truth_and_inside_and_the_outward_move_beyond_the_truth():
    frames, nt, mask, rho = _tube_window()
    truth = frames[2]
    clot = np.flatnonzero((nt == NodeType.CLOT) & mask)
    wall, deep = clot[rho >= 0.95], clot[rho < 0.6]
    excess = functools.partial(wall_excess, truth=jnp.asarray(truth), node_type=nt, mask=mask,
                               stats=_STATS)
    assert float(jnp.abs(excess(jnp.asarray(truth))).max()) == 0.0
    # every clot node moved 0.2 inward: no excess, however wrong the prediction
    inward = truth.copy()
    inward[clot] -= 0.2 * radial(truth[clot])
    assert float(jnp.abs(excess(jnp.asarray(inward))).max()) == 0.0
    # the nodes at the wall moved 0.1 outward: they cross it by about 0.1 - (1 - rho), the
    # truth's own signed distance being negative (inside); the deep nodes moved as far stay in
    out = truth.copy()
    out[wall] += 0.1 * radial(truth[wall])
    out[deep] += 0.1 * radial(truth[deep])
    got = np.asarray(excess(jnp.asarray(out)))
    # by definition: the signed distances of local_wall_plane, the truth's floored at 0
    signed = np.asarray(local_wall_plane(jnp.asarray(out), nt, mask)[0])
    true_signed = np.asarray(local_wall_plane(jnp.asarray(truth), nt, mask)[0])
    np.testing.assert_allclose(got[wall], (signed - np.maximum(true_signed, 0))[wall] / _SIGMA,
                               rtol=1e-5)
    # and near the geometry: the crossing 0.1 - (1 - rho), read from planes of wall nodes a
    # few degrees around (which see less of a radial move: 0.7-0.85 of it here)
    want = (0.1 - (1.0 - rho[rho >= 0.95])) / _SIGMA
    assert ((got[wall] > 0.6 * want) & (got[wall] < 1.05 * want)).all(), got[wall] / want
    assert (got[deep] == 0).all()
    assert (got[~np.isin(np.arange(len(nt)), clot)] == 0).all()  # vessel and padded nodes
    np.testing.assert_allclose(
        float(wall_sum(jnp.asarray(np.stack([out, truth])), jnp.asarray(np.stack([truth, truth])),
                       nt, mask, _STATS)), 0.5 * float(np.sum(got ** 2)), rtol=1e-5)


def test_its_gradient_points_along_the_outward_normal():
    frames, nt, mask, rho = _tube_window()
    truth = frames[2]
    clot = np.flatnonzero((nt == NodeType.CLOT) & mask)
    wall = clot[rho >= 0.95]
    out = truth.copy()
    out[wall] += 0.1 * radial(truth[wall])
    grad = np.asarray(jax.grad(lambda x: wall_sum(x[None], jnp.asarray(truth)[None], nt, mask,
                                                  _STATS))(jnp.asarray(out)))
    g = grad[wall]
    cos = np.sum(g * radial(out[wall]), 1) / np.linalg.norm(g, axis=1)
    assert (cos > 0.98).all()  # descent moves the node back in, along the wall's normal
    assert np.abs(np.delete(grad, wall, axis=0)).max() == 0.0


def test_batch_loss_adds_the_weighted_term_in_both_batch_forms():
    model = create_model("mgn", get_config("mgn", tiny=True))
    batch = window_batch([_tube_window(seed)[:3] for seed in range(2)])
    params = init_state(model, make_optimizer(1e-3), jax.random.PRNGKey(0), batch).params
    step = make_step(model)
    # jitted, as the trainer runs them (op by op, each call compiles ~100 small programs)
    terms = jax.jit(jax.vmap(lambda f, t, m: window_loss_terms(
        step, params, _STATS, f, t, m, train=False, rng=None, wall_term=True)))(
        jnp.asarray(batch.frames), jnp.asarray(batch.node_type), jnp.asarray(batch.mask))
    extra = float(terms["wall_sum"].sum() / terms["count"].sum())
    assert extra > 0  # an untrained model's step puts some wall nodes through it

    @functools.partial(jax.jit, static_argnums=(1, 2))
    def _loss(p, w, flat):
        return batch_loss(model, p, _STATS, batch, None, train=False, flat_batch=flat,
                          wall_loss_weight=w)[0]

    def loss(w, flat=False):
        return float(_loss(params, w, flat))

    np.testing.assert_allclose(loss(4.0), loss(0.0) + 4.0 * extra, rtol=1e-5)
    np.testing.assert_allclose(loss(4.0, flat=True), loss(4.0), rtol=1e-5)


_MODEL = create_model("mgn", get_config("mgn", tiny=True))
_SGD = optax.sgd(3e-3)


@functools.cache
def _sgd_step(weight):
    return make_train_step(_MODEL, _SGD, _STATS, wall_loss_weight=weight, donate=False)


@functools.cache
def _wall_excess():
    """The jitted mean squared wall excess of a batch's one-step predictions, compiled once for
    every seed and weight (the batch an argument, not a constant of the program)."""
    step = make_step(_MODEL)

    @jax.jit
    def excess(params, frames, node_type, mask):
        terms = jax.vmap(lambda f, t, m: window_loss_terms(step, params, _STATS, f, t, m,
                                                           train=False, rng=None,
                                                           wall_term=True))(
            frames, node_type, mask)
        return terms["wall_sum"].sum() / terms["count"].sum()

    return excess


def _excess_after_sgd(weight, seed, steps=4):
    """Mean squared wall excess of a tiny MeshGraphNet's one-step predictions on tube windows
    whose clot touches the wall (radius 1.0-1.02, where the 24-gon's planes read about 0, as the
    data's squeezed clots do), the model's output pushed 3 sigma along +x (so the clot's +x side
    crosses the wall), before and after ``steps`` plain SGD steps on the true targets."""
    batch = window_batch([_tube_window(seed * 10 + i, touch=(1.0, 1.02))[:3] for i in range(4)])
    state = init_state(_MODEL, _SGD, jax.random.PRNGKey(seed), batch)
    params = jax.tree.map(lambda x: x, state.params)
    bias = params["params"]["decoder"]["dense_1"]["bias"]
    params["params"]["decoder"]["dense_1"]["bias"] = bias + jnp.array([3.0, 0.0, 0.0])
    state = dataclasses.replace(state, params=params)

    def excess(p):
        return float(_wall_excess()(p, jnp.asarray(batch.frames), jnp.asarray(batch.node_type),
                                    jnp.asarray(batch.mask)))

    before = excess(state.params)
    for i in range(steps):
        state, _ = _sgd_step(weight)(state, batch, jax.random.PRNGKey(i))
    return before, excess(state.params)


def test_training_with_the_wall_term_takes_the_crossing_out():
    """The same SGD steps from the same model that pushes the clot through the wall: the MSE
    alone shrinks the crossing as it shrinks every error; with the wall term it goes first
    (measured on this CPU, squared excess after 4 steps: seed 0 0.37 -> 0.11 plain, 0.003 with
    the term; seed 1 0.46 -> 0.027 and 0.004)."""
    for seed in range(2):
        before, plain = _excess_after_sgd(0.0, seed)
        _, walled = _excess_after_sgd(10.0, seed)
        assert before > 0.1  # the pushed model puts part of the clot through the wall
        assert walled < 0.5 * plain < before, (before, plain, walled)


def test_the_weight_is_validated_and_needs_the_dense_search():
    with pytest.raises(ConfigError, match="wall_loss_weight"):
        TrainConfig(wall_loss_weight=-1.0)
    cfg = TrainConfig(wall_loss_weight=2.0)
    assert cfg.wall_loss_weight == 2.0
    with pytest.raises(ConfigError, match="--wall-loss-weight"):
        check_dense_inputs(cfg, 10**6)
