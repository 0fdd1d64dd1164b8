"""Erwin (thrombojax.models.erwin): shape, jit + gradients, padding, tree references, permutation.

Tiny config (ErwinConfig.tiny(): hidden 8, two levels, balls of 8, depths 2 so the rotated tree
is used) on N = 50 real nodes (not a power of two: the tree has 64 slots, 14 padding copies).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from thrombojax.graph.balltree import build_balltree_numpy
from thrombojax.models.erwin import BallMSA, ErwinGraph, ErwinSurrogate
from thrombojax.models.registry import count_params, create_model, get_config
from thrombojax.simulator.step import make_input

N = 50


def _inputs(n_real, n_pad=0, seed=0):
    """``n_real`` nodes (the same for a given seed whatever ``n_pad``) then ``n_pad`` junk rows."""
    rows = []
    for n, rng in ((n_real, np.random.default_rng(seed)), (n_pad, np.random.default_rng(99))):
        x = rng.uniform(-1, 1, (n, 3)).astype(np.float32)
        xp = x - 0.05 * rng.normal(size=(n, 3)).astype(np.float32)
        nt = np.where(rng.uniform(size=n) < 0.5, 1, 0).astype(np.int32)
        rows.append((xp, x, nt))
    xp, x, nt = (np.concatenate(a) for a in zip(*rows, strict=True))
    mask = np.arange(n_real + n_pad) < n_real
    return make_input(jnp.asarray(xp), jnp.asarray(x), jnp.asarray(nt), jnp.asarray(mask))


@pytest.fixture(scope="module")
def setup():
    model = create_model("erwin", get_config("erwin", tiny=True))
    inputs = _inputs(N)
    graph = jax.jit(model.build_graph)(inputs)
    params = model.init(jax.random.key(0), inputs, graph)
    apply = jax.jit(model.apply)
    return model, inputs, graph, params, apply


def test_output_shape_finite_and_widths(setup):
    model, inputs, graph, params, apply = setup
    assert isinstance(model, ErwinSurrogate)
    out = apply(params, inputs, graph)
    assert out.shape == (N, 3)
    assert bool(jnp.all(jnp.isfinite(out)))
    assert graph.tree.perm.shape == (64,) and len(graph.tree.rot_perm) == 2
    # widths double per level (hidden 8 -> 16 after one stride-2 pooling)
    net = params["params"]["net"]
    assert net["enc_0"]["pairs"]["plain"]["norm1"]["scale"].shape == (1, 8)  # 1 pair of blocks
    assert net["enc_1"]["pairs"]["rot"]["norm1"]["scale"].shape == (1, 16)
    assert count_params(params) > 0


def test_jit_gradients_finite(setup):
    model, inputs, graph, params, _ = setup

    @jax.jit
    def grads(p):
        return jax.grad(lambda q: jnp.sum(model.apply(q, inputs, graph) ** 2))(p)

    g = grads(params)
    leaves = [np.asarray(leaf) for leaf in jax.tree_util.tree_leaves(g)]  # NumPy: no compiles
    assert all(np.isfinite(leaf).all() for leaf in leaves)
    sigma = np.asarray(g["params"]["net"]["enc_0"]["pairs"]["rot"]["attn"]["sigma"])
    assert np.abs(sigma).sum() > 0.0  # the distance fall-off is trained
    assert sum(np.abs(leaf).sum() for leaf in leaves) > 0.0


def test_padded_rows_leave_real_outputs_unchanged(setup):
    model, inputs, graph, params, apply = setup
    padded = _inputs(N, n_pad=10)  # same real nodes, 10 junk rows; 60 rows keep 64 slots
    graph_p = jax.jit(model.build_graph)(padded)
    out_p = apply(params, padded, graph_p)
    np.testing.assert_allclose(out_p[:N], apply(params, inputs, graph), atol=1e-5, rtol=1e-4)
    assert bool(jnp.all(jnp.isfinite(out_p)))


def test_ball_attention_ignores_padding_slots():
    rng = np.random.default_rng(1)
    x = jnp.asarray(rng.normal(size=(16, 8)), jnp.float32)
    pos = jnp.asarray(rng.uniform(-1, 1, (16, 3)), jnp.float32)
    valid = jnp.asarray([True] * 5 + [False] * 3 + [False] * 8)  # last ball: all padding
    msa = BallMSA(dim=8, num_heads=2, ball_size=8)
    params = msa.init(jax.random.key(0), x, pos, valid)
    out = msa.apply(params, x, pos, valid)
    x2 = x.at[5:].set(100.0 * x[5:] + 3.0)
    pos2 = pos.at[5:].set(7.0)
    out2 = msa.apply(params, x2, pos2, valid)
    np.testing.assert_allclose(out2[:5], out[:5], atol=1e-5, rtol=1e-5)
    assert bool(jnp.all(jnp.isfinite(out2)))


def test_numpy_tree_gives_same_output(setup):
    model, inputs, graph, params, apply = setup
    c = model.config
    tree_np = build_balltree_numpy(
        np.asarray(inputs.positions), mask=np.asarray(inputs.mask), strides=c.strides,
        ball_sizes=c.ball_sizes, rotate=c.rotate,
    )
    tree_np = jax.tree_util.tree_map(jnp.asarray, tree_np)
    graph_np = ErwinGraph(tree=tree_np, neighbors=graph.neighbors)
    np.testing.assert_array_equal(tree_np.perm, graph.tree.perm)
    np.testing.assert_allclose(
        apply(params, inputs, graph_np), apply(params, inputs, graph), atol=1e-6, rtol=1e-5
    )


def test_permuting_nodes_permutes_outputs(setup):
    # Exact up to ties in the tree's median splits (none for random float positions) and
    # float summation order in the MPNN mean.
    model, inputs, graph, params, apply = setup
    perm = np.random.default_rng(2).permutation(N)
    permuted = jax.tree_util.tree_map(lambda a: a[perm], inputs)
    graph_p = jax.jit(model.build_graph)(permuted)
    out = apply(params, inputs, graph)
    np.testing.assert_allclose(apply(params, permuted, graph_p), out[perm], atol=1e-5, rtol=1e-4)


def test_inconsistent_config_raises():
    from thrombojax.errors import ConfigError

    bad = create_model("erwin", get_config("erwin", tiny=True, dec_depths=(2, 2)))
    inputs = _inputs(N)
    with pytest.raises(ConfigError, match="dec_heads"):
        jax.eval_shape(lambda i: bad.init(jax.random.key(0), i, bad.build_graph(i)), inputs)


def test_rotated_tree_is_used(setup):
    # Same parameters without the rotated tree (rotate=0): the odd blocks then run in plain
    # tree order, so the outputs must change.
    model, inputs, graph, params, apply = setup
    plain = create_model("erwin", get_config("erwin", tiny=True, rotate=0.0))
    graph0 = plain.build_graph(inputs)
    assert graph0.tree.rot_perm == ()
    out0 = jax.jit(plain.apply)(params, inputs, graph0)
    assert float(jnp.abs(out0 - apply(params, inputs, graph)).max()) > 1e-7
