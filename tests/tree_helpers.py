"""Parameter-tree helpers shared by the equality tests of the model rewrites."""

import jax
import jax.numpy as jnp
import numpy as np

TOL = 1e-5


def perturbed(params, seed=5):
    """Non-trivial norm scales/biases and non-zero Dense biases, so every term matters.

    The noise is drawn on the host: eager ``jax.random`` per leaf compiles one program per
    leaf shape (about 12 s for Erwin's tree), jitted over the tree one large program."""
    leaves, tree = jax.tree_util.tree_flatten(params)
    rng = np.random.default_rng(seed)
    host = [np.asarray(a) for a in leaves]
    return jax.tree_util.tree_unflatten(tree, [
        jnp.asarray(a + (0.1 * rng.standard_normal(a.shape)).astype(a.dtype)) for a in host
    ])


def assert_trees_close(a, b, tol=TOL):
    """Same structure and every leaf within ``tol`` (absolute and relative)."""
    assert jax.tree_util.tree_structure(a) == jax.tree_util.tree_structure(b)
    for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
        np.testing.assert_allclose(x, y, rtol=tol, atol=tol)
