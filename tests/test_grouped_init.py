"""``thrombojax.models.grouped_init``: the same variables as Flax's ``init``, bit for bit, from a
smaller program (one ``vmap``ed key derivation and draw per group instead of one per array)."""

import re

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import random_model_input

from thrombojax.models import create_model, get_config
from thrombojax.models.grouped_init import grouped_init

CASES = {
    "mgn-remat": ("mgn", {}),  # remat_call: the init skips the custom-vjp transform
    "mgn-plain": ("mgn", {"remat": False, "processor_size": 3}),
    "transolver": ("transolver", {"radius": 0.5}),
    "erwin": ("erwin", {"radius": 0.5}),  # pairs of blocks in nn.scan: drawn in place
}


def _same(a, b):
    assert jax.tree_util.tree_structure(a) == jax.tree_util.tree_structure(b)
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
        assert x.shape == y.shape and x.dtype == y.dtype
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


@pytest.mark.parametrize("case", list(CASES))
def test_grouped_init_equals_flax_init_bit_for_bit(case):
    name, overrides = CASES[case]
    model = create_model(name, get_config(name, tiny=True, **overrides))
    inputs = random_model_input(24, 8, seed=1)
    graph = model.build_graph(inputs)

    def plain(rngs, inputs, graph):
        return dict(model.module.init(rngs, inputs, graph))

    def grouped(rngs, inputs, graph):
        return grouped_init(model.module, rngs, inputs, graph)

    rng = jax.random.key(7)
    rngs = dict(zip(("params", "dropout"), jax.random.split(rng), strict=True))
    want = jax.jit(plain)(rngs, inputs, graph)
    _same(jax.jit(grouped)(rngs, inputs, graph), want)
    _same(model.init(rng, inputs, graph), want)  # the registry's init (it splits the key so)
    if case == "mgn-plain":  # fewer key derivations and draws to compile (one per group)
        calls = [len(re.findall(r"call @_(?:threefry_fold_in|truncated_normal)",
                                jax.jit(f).lower(rngs, inputs, graph).as_text()))
                 for f in (plain, grouped)]
        assert calls[1] < 0.5 * calls[0], calls


class _Boxed(nn.Module):
    """A boxed (partitioned) kernel, a plain one and a non-param variable."""

    @nn.compact
    def __call__(self, x):
        boxed = nn.with_partitioning(nn.initializers.lecun_normal(), ("a", "b"))
        k1 = self.param("boxed", boxed, (x.shape[-1], 4))
        k2 = self.param("plain", nn.initializers.lecun_normal(), (x.shape[-1], 4))
        count = self.variable("stats", "count", lambda: jnp.zeros(()))
        return x @ k1 + x @ k2 + nn.Dense(4)(x) + count.value


def test_boxed_scanned_and_other_variables_are_those_of_flax():
    x = jnp.ones((3, 5))
    rng = jax.random.key(2)
    _same(grouped_init(_Boxed(), rng, x), dict(_Boxed().init(rng, x)))
    jitted = jax.jit(lambda r: grouped_init(_Boxed(), r, x))(rng)
    _same(jitted, dict(jax.jit(lambda r: _Boxed().init(r, x))(rng)))
