"""Coherence that keeps the clot's centroid (``keep_centroid``): shape matching with a tolerance
moves only the nodes beyond it, so a clot stretched on one side (its front leaving the vessel
first) is pulled back along its motion; with ``keep_centroid`` the clot nodes' mean move is taken
out, as shape matching without a tolerance does by construction."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from wall_factory import clot_cloud

from thrombojax.simulator.guards import coherence


def _front_stretched(ref, mask, by=0.6):
    """The clot moved along x with its front half (x above the median) stretched forward."""
    x = ref.copy()
    front = mask & (ref[:, 0] > np.median(ref[mask, 0]))
    x[mask, 0] += 1.0
    x[front, 0] += by * (ref[front, 0] - np.median(ref[mask, 0]))
    return x


def _centroid(x, mask):
    return np.asarray(x)[mask].mean(axis=0)


def _shape_error(x, ref, mask):
    def pairwise(y):
        return np.linalg.norm(y[:, None] - y[None], axis=-1)

    return np.abs(pairwise(np.asarray(x)[mask]) - pairwise(ref[mask])).mean()


def test_keep_centroid_leaves_the_centroid_where_the_step_put_it():
    ref, mask = clot_cloud()
    x = _front_stretched(ref, mask)
    f = jax.jit(lambda a, keep: coherence(a, jnp.asarray(ref), jnp.asarray(mask), stiffness=1.0,
                                          tolerance=0.1, keep_centroid=keep),
                static_argnames="keep")
    pulled, _ = f(jnp.asarray(x), keep=False)
    kept, corr = f(jnp.asarray(x), keep=True)
    # without: the stretched front is pulled back, and the centroid with it
    assert _centroid(pulled, mask)[0] < _centroid(x, mask)[0] - 0.02
    np.testing.assert_allclose(_centroid(kept, mask), _centroid(x, mask), atol=1e-5)
    # the shape is corrected as much either way: the same moves, less their mean
    assert _shape_error(kept, ref, mask) < 0.5 * _shape_error(x, ref, mask)
    np.testing.assert_allclose(_shape_error(kept, ref, mask), _shape_error(pulled, ref, mask),
                               rtol=1e-4, atol=1e-6)
    np.testing.assert_array_equal(np.asarray(kept)[~mask], x[~mask])
    np.testing.assert_array_equal(np.asarray(corr)[~mask], 0.0)
    # a clot within the tolerance is not moved at all
    still, none = f(jnp.asarray(ref + [1.0, 0.0, 0.0]), keep=True)
    np.testing.assert_array_equal(np.asarray(none), 0.0)


def test_build_guards_passes_keep_centroid_to_the_rollout_guard():
    from wall_factory import straight_tube

    from thrombojax.simulator.guard_set import build_guards
    from thrombojax.types import NodeType

    x0, node_type = straight_tube()
    clot = node_type == NodeType.CLOT
    x = x0.copy()
    x[clot, 0] += np.where(x0[clot, 0] > 0, 0.8 * x0[clot, 0], 0.0)  # front stretched along x
    for keep in (False, True):
        guards = build_guards(x0, node_type, x0, node_type, radius=1.0, containment=False,
                              tolerance_r=0.05, keep_centroid=keep)
        assert guards.keep_centroid is keep
        out, corr = jax.jit(guards.apply)(jnp.asarray(x))
        shift = _centroid(out, clot)[0] - _centroid(x, clot)[0]
        assert float(np.asarray(corr["coherence"]).max()) > 0.05
        assert (abs(shift) < 1e-5) if keep else (shift < -0.01), (keep, shift)  # -0.016
