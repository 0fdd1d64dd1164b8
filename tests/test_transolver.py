"""Acceptance tests of Transolver (tiny config): shape, jit + gradients, padding, permutation,
slice weights and dropout."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import random_model_input

from thrombojax import study
from thrombojax.errors import ConfigError
from thrombojax.models import create_model, get_config
from thrombojax.models.transolver import PhysicsAttention, TransolverSurrogate

N_REAL, N_PAD = 30, 10


def _inputs(n_real=N_REAL, n_pad=N_PAD, seed=0):
    return random_model_input(n_real, n_pad, seed)


@pytest.fixture(scope="module")
def model():
    return create_model("transolver", get_config("transolver", tiny=True, radius=0.5))


@pytest.fixture(scope="module")
def forward(model):
    @jax.jit
    def fwd(params, inputs, rng):
        graph = model.build_graph(inputs)
        return (
            model.apply(params, inputs, graph),
            model.apply(params, inputs, graph, train=True, rng=rng),
        )

    return fwd


@pytest.fixture(scope="module")
def params(model):
    inputs = _inputs()
    return model.init(jax.random.key(1), inputs, model.build_graph(inputs))


def test_registry_builds_transolver(model):
    assert isinstance(model, TransolverSurrogate)
    assert model.config.dropout > 0.0


def test_output_shape_and_dropout(forward, params):
    rng = jax.random.key(2)
    out, out_train = forward(params, _inputs(), rng)
    assert out.shape == (N_REAL + N_PAD, 3)
    assert np.all(np.isfinite(out)) and np.all(np.isfinite(out_train))
    # dropout only in training, driven by rng
    again, again_train = forward(params, _inputs(), rng)
    np.testing.assert_array_equal(out, again)
    np.testing.assert_array_equal(out_train, again_train)
    _, other_train = forward(params, _inputs(), jax.random.key(3))
    assert not np.allclose(out_train, out)
    assert not np.allclose(out_train, other_train)


def test_train_without_rng_is_rejected(model, params):
    inputs = _inputs()
    with pytest.raises(ConfigError, match="rng"):
        model.apply(params, inputs, model.build_graph(inputs), train=True)


def test_jit_and_finite_gradients(model, params):
    inputs = _inputs()
    graph = model.build_graph(inputs)

    @jax.jit
    def loss(p, rng):
        out = model.apply(p, inputs, graph, train=True, rng=rng)
        return jnp.sum(jnp.where(inputs.mask[:, None], out, 0.0) ** 2)

    grads = jax.grad(loss)(params, jax.random.key(4))
    leaves = jax.tree_util.tree_leaves_with_path(grads)
    assert all(np.all(np.isfinite(g)) for _, g in leaves)
    dead = [jax.tree_util.keystr(p) for p, g in leaves if float(np.max(np.abs(g))) == 0.0]
    assert dead == []


def test_padded_nodes_do_not_change_real_outputs(forward, params):
    padded = _inputs(seed=3)
    unpadded = jax.tree_util.tree_map(lambda a: a[:N_REAL], padded)
    other = _inputs(seed=9)  # different garbage in the padded rows
    other = jax.tree_util.tree_map(lambda a, b: b.at[:N_REAL].set(a[:N_REAL]), padded, other)
    rng = jax.random.key(0)
    ref, _ = forward(params, unpadded, rng)
    for inputs in (padded, other):
        out, _ = forward(params, inputs, rng)
        np.testing.assert_allclose(out[:N_REAL], ref, rtol=1e-5, atol=1e-5)


def test_permuting_nodes_permutes_outputs(forward, params):
    inputs = _inputs(seed=4)
    perm = jax.random.permutation(jax.random.key(5), N_REAL + N_PAD)
    permuted = jax.tree_util.tree_map(lambda a: a[perm], inputs)
    out, _ = forward(params, inputs, jax.random.key(0))
    out_p, _ = forward(params, permuted, jax.random.key(0))
    real = np.asarray(permuted.mask)
    np.testing.assert_allclose(out_p[real], out[perm][real], rtol=1e-5, atol=1e-5)


def test_physics_attention_slice_tokens_ignore_padding():
    """With one slice, the slice token is the mask-weighted mean: padded rows cannot move it."""
    x = jax.random.normal(jax.random.key(0), (7, 4))
    mask = jnp.array([True] * 5 + [False] * 2)
    attn = PhysicsAttention(heads=2, slices=1)
    p = attn.init(jax.random.key(1), x, mask)
    y = attn.apply(p, x, mask)
    y_garbage = attn.apply(p, x.at[5:].set(1e3), mask)
    np.testing.assert_allclose(y[:5], y_garbage[:5], rtol=1e-5, atol=1e-5)
    # one slice: every real token gets the same output (deslice of the single token)
    np.testing.assert_allclose(y[:5], jnp.broadcast_to(y[0], (5, 4)), rtol=1e-5, atol=1e-6)


def test_study_defaults():
    cfg = get_config("transolver")
    assert (cfg.hidden, cfg.heads, cfg.layers, cfg.slices) == (64, 16, 5, 24)
    assert (cfg.dropout, cfg.radius) == (0.576, 0.576)
    assert study.training_defaults("transolver") == {"batch_size": 16, "lr": 1e-4}
