"""The training-speed and memory rewrites equal the plain forms they replace (issue 17).

Each rewrite (factorised first layer of MeshGraphNet's edge MLP, slot-sum aggregation,
rematerialisation, the split message layer of the MPNN embedding) keeps the parameter tree and
gives the same outputs and gradients as the plain form, to 1e-5, on a padded random graph.
"""

import dataclasses

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import random_model_input
from tree_helpers import assert_trees_close, perturbed

from thrombojax.models import create_model, get_config
from thrombojax.models.layers import MPNNEmbedding, SplitDense
from thrombojax.models.meshgraphnet import MeshGraphNet

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)

N_REAL, N_PAD = 40, 8
TOL = 1e-5


def test_split_dense_is_dense_of_the_concatenation():
    parts = [jax.random.normal(jax.random.key(i), (7, d)) for i, d in enumerate((3, 5, 2))]
    dense, split = nn.Dense(4), SplitDense(4, bias_part=1)
    p_dense = dense.init(jax.random.key(0), jnp.concatenate(parts, -1))
    p_split = split.init(jax.random.key(0), *parts)
    assert_trees_close(p_dense, p_split, tol=0.0)  # same names, shapes and initial values
    p = perturbed(p_dense)

    def f_dense(p, parts):
        return jnp.sum(jnp.sin(dense.apply(p, jnp.concatenate(parts, -1))))

    def f_split(p, parts):
        return jnp.sum(jnp.sin(sum(split.apply(p, *parts))))

    np.testing.assert_allclose(f_split(p, parts), f_dense(p, parts), rtol=TOL)
    assert_trees_close(jax.grad(f_split, argnums=(0, 1))(p, parts),
                        jax.grad(f_dense, argnums=(0, 1))(p, parts))


@pytest.fixture(scope="module")
def mgn_case():
    # the plain reference: no remat (MeshGraphNet's default is remat on)
    config = get_config("mgn", tiny=True, radius=0.5, hidden=16, mlp_layers=2, remat=False)
    model = create_model("mgn", config)
    inputs = random_model_input(N_REAL, N_PAD, seed=2)
    graph = model.build_graph(inputs)
    assert int(jnp.sum(graph.indices < graph.indices.shape[0])) > 0  # real edges
    assert bool(jnp.any(graph.indices == graph.indices.shape[0]))  # and sentinel slots
    return config, inputs, graph


def _mgn_loss(config, factorised, slot_sum, inputs, graph):
    module = MeshGraphNet(config, factorised=factorised, slot_sum=slot_sum)
    target = jnp.cos(jnp.arange(inputs.n_nodes * 3.0)).reshape(-1, 3)

    def loss(params):
        out = module.apply(params, inputs, graph)
        err = jnp.where(inputs.mask[:, None], out - target, 0.0)
        return jnp.sum(err**2), out[:N_REAL]

    return module, jax.jit(jax.value_and_grad(loss, has_aux=True))


@pytest.fixture(scope="module")
def mgn_plain(mgn_case):
    """The plain form's initial parameters, and its loss, outputs and gradients at their
    perturbation: computed once, the reference of every rewrite below."""
    config, inputs, graph = mgn_case
    plain, plain_fn = _mgn_loss(config, False, False, inputs, graph)
    initial = plain.init(jax.random.key(1), inputs, graph)
    params = perturbed(initial)
    return initial, params, plain_fn(params)


@pytest.mark.parametrize(
    "factorised, slot_sum, remat",
    [(True, False, False), (False, True, False), (True, True, False), (True, False, True),
     (True, True, True)],
    ids=["factorised", "slot_sum", "both", "factorised+remat (default)", "both+remat"],
)
def test_meshgraphnet_rewrites_equal_plain(mgn_case, mgn_plain, factorised, slot_sum, remat):
    config, inputs, graph = mgn_case
    initial, params, ((loss_p, out_p), grads_p) = mgn_plain
    fast_config = dataclasses.replace(config, remat=remat)
    fast, fast_fn = _mgn_loss(fast_config, factorised, slot_sum, inputs, graph)
    assert_trees_close(fast.init(jax.random.key(1), inputs, graph), initial, tol=0.0)
    (loss_f, out_f), grads_f = fast_fn(params)
    assert float(jnp.std(out_p)) > 0.0
    np.testing.assert_allclose(out_f, out_p, rtol=TOL, atol=TOL)
    np.testing.assert_allclose(loss_f, loss_p, rtol=TOL)
    assert_trees_close(grads_f, grads_p)
    assert all(float(np.max(np.abs(g))) > 0 for g in jax.tree_util.tree_leaves(grads_p))


def test_the_default_meshgraphnet_is_factorised_with_remat():
    """The study config and the tiny one train with remat (the equality above covers it)."""
    assert get_config("mgn").remat and get_config("mgn", tiny=True).remat
    assert not get_config("mgn", remat=False).remat


def test_remat_lowers_the_compiled_peak(mgn_case):
    """Rematerialisation is a memory lever: the compiled gradient's temporaries shrink."""
    config, inputs, graph = mgn_case
    big = dataclasses.replace(config, processor_size=4, max_neighbors=16)
    model = create_model("mgn", big)
    graph = model.build_graph(inputs)
    params = model.init(jax.random.key(0), inputs, graph)

    def temp_bytes(remat):
        module = MeshGraphNet(dataclasses.replace(big, remat=remat))
        grad = jax.grad(lambda p: jnp.sum(module.apply(p, inputs, graph) ** 2))
        return jax.jit(grad).lower(params).compile().memory_analysis().temp_size_in_bytes

    assert temp_bytes(True) < temp_bytes(False)


@pytest.mark.parametrize("steps", [1, 2])
def test_mpnn_split_message_equals_concatenation(steps):
    n, k = 12, 5
    keys = jax.random.split(jax.random.key(3), 3)
    feats, pos = jax.random.normal(keys[0], (n, 6)), jax.random.normal(keys[1], (n, 3))
    nbrs = jax.random.randint(keys[2], (n, k), 0, n + 1)  # sentinel n in some slots
    nbrs = nbrs.at[0].set(n)  # a node without neighbours
    split, plain = MPNNEmbedding(8, steps, split=True), MPNNEmbedding(8, steps, split=False)
    params = plain.init(jax.random.key(0), feats, pos, nbrs)
    assert_trees_close(split.init(jax.random.key(0), feats, pos, nbrs), params, tol=0.0)
    params = perturbed(params)

    def loss(module):
        return jax.jit(jax.value_and_grad(
            lambda p, x: jnp.sum(jnp.tanh(module.apply(p, x, pos, nbrs))), argnums=(0, 1)))

    (val_s, grads_s), (val_p, grads_p) = loss(split)(params, feats), loss(plain)(params, feats)
    np.testing.assert_allclose(val_s, val_p, rtol=TOL)
    np.testing.assert_allclose(split.apply(params, feats, pos, nbrs),
                               plain.apply(params, feats, pos, nbrs), rtol=TOL, atol=TOL)
    assert_trees_close(grads_s, grads_p)
