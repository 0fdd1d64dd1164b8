"""Parameter-tree helpers shared by the equality tests of the model rewrites."""

import jax
import numpy as np

TOL = 1e-5


def perturbed(params, seed=5):
    """Non-trivial norm scales/biases and non-zero Dense biases, so every term matters."""
    leaves, tree = jax.tree_util.tree_flatten(params)
    keys = jax.random.split(jax.random.key(seed), len(leaves))
    return jax.tree_util.tree_unflatten(
        tree, [a + 0.1 * jax.random.normal(k, a.shape) for a, k in zip(leaves, keys, strict=True)]
    )


def assert_trees_close(a, b, tol=TOL):
    """Same structure and every leaf within ``tol`` (absolute and relative)."""
    assert jax.tree_util.tree_structure(a) == jax.tree_util.tree_structure(b)
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
        np.testing.assert_allclose(x, y, rtol=tol, atol=tol)
