"""Coherence that frees the clot nodes past an open end of the wall (``free_past_end``): the part
of a clot that has left the vessel through its outlet is neither pulled back to the copy of the
start frame nor part of that copy's fit; the nodes the vessel still holds are guarded as
before."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from wall_factory import straight_tube

from thrombojax.simulator.guard_set import build_guards
from thrombojax.types import NodeType


def _leaving():
    """The tube's start frame, and a frame whose clot nodes with ``x > 0`` left the tube through
    its end at ``x = 2`` (moved 3 along it) while the others stay where they were."""
    x0, node_type = straight_tube()
    clot = node_type == NodeType.CLOT
    front = clot & (x0[:, 0] > 0)
    x = x0.copy()
    x[front] += [3.0, 0.0, 0.0]
    return x0, node_type, clot, front, x


def _coherence(x0, node_type, x, free: bool):
    guards = build_guards(x0, node_type, x0, node_type, radius=1.0, containment=False,
                          tolerance_r=0.0, free_past_end=free)
    assert guards.free_past_end is free
    out, corr = jax.jit(guards.apply)(jnp.asarray(x))
    return np.asarray(out), np.asarray(corr["coherence"])


def test_nodes_past_the_outlet_are_not_pulled_back():
    x0, node_type, clot, front, x = _leaving()
    assert 5 < front.sum() < clot.sum() - 5
    _, pulled = _coherence(x0, node_type, x, free=False)
    out, corr = _coherence(x0, node_type, x, free=True)
    assert pulled[front].min() > 0.5 and pulled[clot & ~front].min() > 0.5  # rigid copy: all move
    # freed: the front stays where the step put it, and the back, still rigid, is not moved
    np.testing.assert_allclose(out, x, atol=1e-5)
    assert corr.max() < 1e-4, corr.max()


def test_the_nodes_the_vessel_holds_are_still_guarded():
    x0, node_type, clot, front, x = _leaving()
    back = np.flatnonzero(clot & ~front)
    x[back[0]] += [0.0, 0.3, 0.0]  # one held node strays from the clot's shape
    out, corr = _coherence(x0, node_type, x, free=True)
    assert corr[back[0]] > 0.2
    np.testing.assert_allclose(out[front], x[front], atol=1e-5)
    np.testing.assert_array_equal(corr[node_type != NodeType.CLOT], 0.0)


def test_a_clot_wholly_inside_is_guarded_as_without_the_option():
    x0, node_type = straight_tube()
    clot = node_type == NodeType.CLOT
    x = x0.copy()
    x[clot] += np.random.default_rng(1).normal(scale=0.1, size=(clot.sum(), 3))
    held_out, held_corr = _coherence(x0, node_type, x, free=True)
    out, corr = _coherence(x0, node_type, x, free=False)
    assert corr.max() > 0.05
    np.testing.assert_allclose(held_out, out, atol=1e-5)
    np.testing.assert_allclose(held_corr, corr, atol=1e-5)
