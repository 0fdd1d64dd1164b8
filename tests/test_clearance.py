"""The clot's clearance: the distance from its centroid to the nearest vessel node, as a node
input (:func:`thrombojax.graph.clearance.clot_clearance`, ``make_step(...,
clearance_radius=L)``, ``thrombojax train --clearance-features L``)."""

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from thrombojax.graph.clearance import CLEARANCE_FEATURES, clot_clearance
from thrombojax.types import NodeType

ROT = Rotation.from_euler("xyz", [0.4, 2.1, -1.3]).as_matrix().astype(np.float32)


def _clot_in_ring(rng, radius=2.0, n_clot=40, sigma=0.25, speed=0.05, accel=0.0):
    """Three frames of a ball of ``n_clot`` clot nodes moving along x through a fixed ring of 16
    vessel nodes of ``radius`` in the plane x = 0 (the middle frame at x ~ 0): ``speed`` per
    frame into the middle frame, ``speed + accel`` out of it (so ``accel`` shows in the target
    alone, not in the input velocity); 4 padded clot nodes far away last. Returns ``(frames
    [3, N, 3], node_type, mask)`` numpy arrays."""
    ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    ring = np.stack([np.zeros(16), radius * np.cos(ang), radius * np.sin(ang)], axis=1)
    clot = rng.normal(size=(n_clot, 3)) * sigma
    x = np.concatenate([ring, clot, np.full((4, 3), 9.0)]).astype(np.float32)
    nt = np.array([NodeType.VESSEL] * 16 + [NodeType.CLOT] * (n_clot + 4), np.int32)
    mask = np.arange(len(x)) < 16 + n_clot
    moving = (nt == NodeType.CLOT) & mask
    out = np.repeat(x[None], 3, axis=0)
    out[:, moving, 0] += np.array([-speed, 0.0, speed + accel], np.float32)[:, None]
    return out, nt, mask


def _reference(x, nt, mask, scale):
    clot = (nt == NodeType.CLOT) & mask
    vessel = (nt == NodeType.VESSEL) & mask
    centre = x[clot].mean(0)
    return np.linalg.norm(x[vessel] - centre, axis=1).min() / scale


def test_clearance_is_the_centroid_distance_to_the_nearest_vessel_node_on_clot_nodes():
    frames, nt, mask = _clot_in_ring(np.random.default_rng(0))
    x = frames[1]
    out = np.asarray(clot_clearance(jnp.asarray(x), nt, mask, scale=0.5))
    assert out.shape == (len(x), CLEARANCE_FEATURES)
    clot = (nt == NodeType.CLOT) & mask
    np.testing.assert_allclose(out[clot, 0], _reference(x, nt, mask, 0.5), rtol=1e-5)
    assert 3.5 < out[clot, 0].mean() < 4.5  # ~2 / 0.5: the centroid is near the ring's centre
    assert np.all(out[~clot] == 0.0)  # vessel and padded nodes (padded clot nodes far away)
    # no vessel node, or no clot node: zeros, not a distance to nowhere
    assert np.all(np.asarray(clot_clearance(jnp.asarray(x), np.full_like(nt, NodeType.CLOT),
                                            mask, scale=0.5)) == 0.0)
    assert np.all(np.asarray(clot_clearance(jnp.asarray(x), nt, mask & (nt != NodeType.CLOT),
                                            scale=0.5)) == 0.0)
    with pytest.raises(ValueError, match="scale"):
        clot_clearance(jnp.asarray(x), nt, mask, scale=0.0)


def test_clearance_is_invariant_to_rotations_and_translations_and_to_moving_single_nodes():
    """It reads the clot through its centroid alone: turning and shifting the frame leaves it,
    and a guard-like correction of a few boundary nodes (0.1 of the radius, 3 of 40 nodes)
    moves it far less than it moves those nodes."""
    frames, nt, mask = _clot_in_ring(np.random.default_rng(1))
    x = frames[1]
    base = np.asarray(clot_clearance(jnp.asarray(x), nt, mask, scale=1.0))
    shift = np.array([3.0, -7.0, 2.0], np.float32)
    turned = np.asarray(clot_clearance(jnp.asarray(x @ ROT.T + shift), nt, mask, scale=1.0))
    np.testing.assert_allclose(turned, base, atol=2e-5)
    moved = x.copy()
    idx = 16 + np.arange(3)
    moved[idx] -= 0.2 * moved[idx] / np.linalg.norm(moved[idx], axis=1, keepdims=True)
    after = np.asarray(clot_clearance(jnp.asarray(moved), nt, mask, scale=1.0))
    clot = (nt == NodeType.CLOT) & mask
    assert abs(after[clot, 0].mean() - base[clot, 0].mean()) < 0.2 * 3 / 40 + 1e-6


def test_clearance_reaches_the_model_and_the_training_config():
    """A step with ``clearance_radius`` reads 1 more input per node, this feature; a negative
    length is refused by the step and by the training options."""
    from dataset_factory import check_step_input_option

    frames, nt, mask = _clot_in_ring(np.random.default_rng(2), n_clot=24)
    prev, cur = jnp.asarray(frames[0]), jnp.asarray(frames[1])
    check_step_input_option(prev, cur, nt, mask, "clearance_radius", 0.5, CLEARANCE_FEATURES,
                            clot_clearance(cur, nt, mask, scale=0.5), "clearance_features",
                            atol=1e-6)


def _speed_change_error(clearance_radius: float) -> float:
    """:func:`dataset_factory.width_speed_error` on this module's clots."""
    from dataset_factory import width_speed_error

    def window(rng, radius, accel):
        return _clot_in_ring(rng, radius=radius, accel=accel)

    return width_speed_error(window, "clearance_radius", clearance_radius)


def test_clearance_lets_a_step_see_the_width_that_sets_the_speed():
    """Fails without the feature: the ring that sets each clot's acceleration is out of the
    graph's reach, so the tiny step learns the mean (error about 2/3 of the spread); given the
    clearance it tells the three rings apart."""
    without = _speed_change_error(0.0)
    with_it = _speed_change_error(1.0)
    assert without > 0.5
    assert with_it < 0.3 * without
