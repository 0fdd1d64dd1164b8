"""Tests of the shared building blocks in thrombojax.models.layers."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from thrombojax.models.layers import (
    LAYER_NORM_EPS,
    MLP,
    MPNNEmbedding,
    RMSNorm,
    SwiGLU,
    gather_neighbors,
    gelu,
    neighbor_mask,
)


def _x(shape, seed=0):
    return jax.random.normal(jax.random.key(seed), shape)


def test_gelu_is_exact_erf_form():
    x = jnp.linspace(-3.0, 3.0, 13)
    exact = x * 0.5 * (1.0 + jax.scipy.special.erf(x / np.sqrt(2.0)))
    np.testing.assert_allclose(gelu(x), exact, atol=1e-6)
    assert not np.allclose(gelu(x), jax.nn.gelu(x, approximate=True), atol=1e-5)


def test_mlp_layers_and_layer_norm():
    x = _x((5, 4))
    mlp = MLP((6, 7, 3), layer_norm=True)
    params = mlp.init(jax.random.key(1), x)
    kernels = [params["params"][f"dense_{i}"]["kernel"].shape for i in range(3)]
    assert kernels == [(4, 6), (6, 7), (7, 3)]
    y = mlp.apply(params, x)
    assert y.shape == (5, 3)
    # LayerNorm with unit scale, zero bias: zero mean, unit variance per row
    np.testing.assert_allclose(jnp.mean(y, -1), 0.0, atol=1e-5)
    np.testing.assert_allclose(jnp.var(y, -1), 1.0, atol=1e-2)
    assert "norm" in params["params"]
    plain = MLP((6, 3))
    assert "norm" not in plain.init(jax.random.key(1), x)["params"]


def test_mlp_matches_manual_forward():
    x = _x((3, 4))
    mlp = MLP((5, 2), activation=jax.nn.relu)
    p = mlp.init(jax.random.key(2), x)["params"]
    h = jax.nn.relu(x @ p["dense_0"]["kernel"] + p["dense_0"]["bias"])
    ref = h @ p["dense_1"]["kernel"] + p["dense_1"]["bias"]
    np.testing.assert_allclose(mlp.apply({"params": p}, x), ref, rtol=1e-5, atol=1e-6)


def test_rms_norm_formula():
    x = _x((4, 6)) * 3.0
    norm = RMSNorm(epsilon=1e-6)
    assert norm.init(jax.random.key(0), x)["params"]["scale"].shape == (6,)
    params = {"params": {"scale": jnp.arange(1.0, 7.0)}}
    ref = x / jnp.sqrt(jnp.mean(x**2, -1, keepdims=True) + 1e-6) * jnp.arange(1.0, 7.0)
    np.testing.assert_allclose(norm.apply(params, x), ref, rtol=1e-5)


def test_swiglu_formula():
    x = _x((4, 3))
    mod = SwiGLU(8)
    p = mod.init(jax.random.key(3), x)["params"]

    def lin(name, v):
        return v @ p[name]["kernel"] + p[name]["bias"]

    ref = lin("w3", jax.nn.silu(lin("w1", x)) * lin("w2", x))
    assert p["w3"]["kernel"].shape == (8, 3)
    np.testing.assert_allclose(mod.apply({"params": p}, x), ref, rtol=1e-5, atol=1e-6)


def test_gather_neighbors_reads_zero_at_sentinel():
    x = jnp.arange(6.0).reshape(3, 2) + 1.0
    nbrs = jnp.array([[1, 3], [3, 3], [0, 2]])
    got = gather_neighbors(x, nbrs)
    np.testing.assert_array_equal(got[0, 0], x[1])
    np.testing.assert_array_equal(got[0, 1], [0.0, 0.0])
    expected = [[True, False], [False, False], [True, True]]
    np.testing.assert_array_equal(neighbor_mask(nbrs), expected)


def _layer_norm(v, scale, bias):
    mu = v.mean(-1, keepdims=True)
    var = ((v - mu) ** 2).mean(-1, keepdims=True)
    return (v - mu) / np.sqrt(var + LAYER_NORM_EPS) * scale + bias


def _mpnn_reference(p, feats, pos, edges, steps):
    """Edge-list loop implementation of the documented MPNN equations (numpy, float64)."""
    p = jax.tree_util.tree_map(lambda a: np.asarray(a, np.float64), p)
    feats, pos = np.asarray(feats, np.float64), np.asarray(pos, np.float64)
    erf = np.vectorize(__import__("math").erf)
    h = feats @ p["embed"]["kernel"] + p["embed"]["bias"]
    for s in range(steps):
        msum = np.zeros_like(h)
        cnt = np.zeros(len(h))
        for j, i in edges:  # sender j -> receiver i
            z = np.concatenate([h[j], h[i], pos[j] - pos[i]])
            z = z @ p[f"message_{s}"]["kernel"] + p[f"message_{s}"]["bias"]
            z = 0.5 * z * (1 + erf(z / np.sqrt(2)))
            ln = p[f"message_norm_{s}"]
            msum[i] += _layer_norm(z, ln["scale"], ln["bias"])
            cnt[i] += 1
        m = msum / np.maximum(cnt, 1)[:, None]
        u = np.concatenate([h, m], -1) @ p[f"update_{s}"]["kernel"] + p[f"update_{s}"]["bias"]
        ln = p[f"update_norm_{s}"]
        h = h + _layer_norm(u, ln["scale"], ln["bias"])
    return h


@pytest.mark.parametrize("steps", [0, 2])
def test_mpnn_embedding_matches_edge_list_reference(steps):
    n = 6
    feats, pos = _x((n, 5), 1), _x((n, 3), 2)
    nbrs = jnp.array([[1, 2, 6], [0, 6, 6], [0, 1, 3], [6, 6, 6], [5, 3, 6], [4, 6, 6]])
    mod = MPNNEmbedding(dim=8, mp_steps=steps)
    params = mod.init(jax.random.key(0), feats, pos, nbrs)
    # perturb LayerNorm parameters so they are exercised
    params = jax.tree_util.tree_map_with_path(
        lambda path, a: a + 0.1 * _x(a.shape, 7) if "norm" in str(path) else a, params
    )
    got = jax.jit(mod.apply)(params, feats, pos, nbrs)
    edges = [(int(j), i) for i in range(n) for j in np.asarray(nbrs[i]) if j < n]
    ref = _mpnn_reference(params["params"], feats, pos, edges, steps)
    assert got.shape == (n, 8)
    np.testing.assert_allclose(got, ref, rtol=2e-4, atol=2e-4)


def test_mpnn_embedding_translation_invariant():
    feats, pos = _x((5, 4), 1), _x((5, 3), 2)
    nbrs = jnp.array([[1, 2], [0, 5], [0, 1], [4, 5], [3, 5]])
    mod = MPNNEmbedding(dim=8, mp_steps=2)
    params = mod.init(jax.random.key(0), feats, pos, nbrs)
    a = mod.apply(params, feats, pos, nbrs)
    b = mod.apply(params, feats, pos + jnp.array([0.3, -0.7, 0.2]), nbrs)
    np.testing.assert_allclose(a, b, atol=1e-5)
