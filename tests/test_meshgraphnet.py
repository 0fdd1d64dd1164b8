"""Acceptance tests of MeshGraphNet (tiny config): shape, jit + gradients, padding, symmetry."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import random_model_input

from thrombojax.models import create_model, get_config
from thrombojax.models.meshgraphnet import MeshGraphNetSurrogate

N_REAL, N_PAD = 30, 10


def _inputs(n_real=N_REAL, n_pad=N_PAD, seed=0):
    return random_model_input(n_real, n_pad, seed)


@pytest.fixture(scope="module")
def model():
    return create_model("mgn", get_config("mgn", tiny=True, radius=0.5))


@pytest.fixture(scope="module")
def forward(model):
    @jax.jit
    def fwd(params, inputs):
        graph = model.build_graph(inputs)
        return model.apply(params, inputs, graph), graph.counts

    return fwd


@pytest.fixture(scope="module")
def params(model):
    inputs = _inputs()
    return model.init(jax.random.key(1), inputs, model.build_graph(inputs))


def test_registry_builds_meshgraphnet(model):
    assert isinstance(model, MeshGraphNetSurrogate)
    assert create_model("meshgraphnet").config == get_config("mgn")


def test_output_shape_and_finite(forward, params):
    out, counts = forward(params, _inputs())
    assert out.shape == (N_REAL + N_PAD, 3)
    assert np.all(np.isfinite(out))
    assert counts.shape == (N_REAL + N_PAD,)
    assert float(jnp.std(out[:N_REAL])) > 0.0


def test_jit_and_finite_gradients(model, params):
    inputs = _inputs()
    graph = model.build_graph(inputs)

    @jax.jit
    def loss(p):
        out = model.apply(p, inputs, graph, train=True)
        return jnp.sum(jnp.where(inputs.mask[:, None], out, 0.0) ** 2)

    grads = jax.grad(loss)(params)
    leaves = jax.tree_util.tree_leaves(grads)
    assert all(np.all(np.isfinite(g)) for g in leaves)
    # every parameter of the network receives signal (processor blocks included)
    assert all(float(np.max(np.abs(g))) > 0.0 for g in leaves)


def test_padded_nodes_do_not_change_real_outputs(forward, params):
    padded = _inputs(n_pad=N_PAD, seed=3)
    unpadded = jax.tree_util.tree_map(lambda a: a[:N_REAL], padded)
    other = _inputs(n_pad=N_PAD, seed=9)  # different garbage in the padded rows
    other = jax.tree_util.tree_map(lambda a, b: b.at[:N_REAL].set(a[:N_REAL]), padded, other)
    ref, _ = forward(params, unpadded)
    for inputs in (padded, other):
        out, _ = forward(params, inputs)
        np.testing.assert_allclose(out[:N_REAL], ref, rtol=1e-5, atol=1e-5)


def test_permuting_nodes_permutes_outputs(forward, params):
    inputs = _inputs(seed=4)
    perm = jax.random.permutation(jax.random.key(5), N_REAL + N_PAD)
    permuted = jax.tree_util.tree_map(lambda a: a[perm], inputs)
    out, _ = forward(params, inputs)
    out_p, _ = forward(params, permuted)
    real = np.asarray(permuted.mask)
    np.testing.assert_allclose(out_p[real], out[perm][real], rtol=1e-5, atol=1e-5)


def test_translation_invariant(forward, params):
    inputs = _inputs(seed=6)
    shifted = inputs.replace(positions=inputs.positions + jnp.array([0.25, -0.4, 0.1]))
    out, _ = forward(params, inputs)
    out_s, _ = forward(params, shifted)
    np.testing.assert_allclose(out_s[:N_REAL], out[:N_REAL], rtol=1e-4, atol=1e-4)
    # but not blind to geometry: changing relative positions changes the output
    squeezed = inputs.replace(positions=inputs.positions * 0.7)
    out_q, _ = forward(params, squeezed)
    assert not np.allclose(out_q[:N_REAL], out[:N_REAL], atol=1e-3)


def test_study_config_parameter_count():
    """Hidden 64, 15 blocks, 2-hidden-layer MLPs: the PhysicsNeMo layout, counted by hand."""
    cfg = get_config("mgn")
    h, lay = cfg.hidden, cfg.mlp_layers

    def mlp(d_in, d_out, norm=True):
        dims = [d_in] + [h] * lay + [d_out]
        dense = sum(a * b + b for a, b in zip(dims[:-1], dims[1:], strict=True))
        return dense + (2 * d_out if norm else 0)

    expected = mlp(5, h) + mlp(4, h) + cfg.processor_size * (mlp(3 * h, h) + mlp(2 * h, h))
    expected += mlp(h, 3, norm=False)
    model = create_model("mgn", cfg)
    inputs = _inputs(n_real=8, n_pad=0)
    shapes = jax.eval_shape(model.init, jax.random.key(0), inputs, model.build_graph(inputs))
    assert sum(int(np.prod(x.shape)) for x in jax.tree_util.tree_leaves(shapes)) == expected
