"""The vessel's width at the clot as a node input (:func:`thrombojax.graph.section
.clot_section_features`, ``make_step(..., section_radius=L)``, ``thrombojax train
--section-features L``)."""

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from thrombojax.graph.clearance import clot_clearance
from thrombojax.graph.section import SECTION_FEATURES, clot_section_features, section_width
from thrombojax.types import NodeType

ROT = Rotation.from_euler("xyz", [0.4, 2.1, -1.3]).as_matrix().astype(np.float32)


def _tube(radius_at, length=8.0, spacing=0.25, around=16):
    """Wall nodes of a tube along x from ``-length / 2`` to ``length / 2`` whose radius at ``x``
    is ``radius_at(x)``; rings ``spacing`` apart, ``around`` nodes each (alternate rings turned
    by half a step, as a mesh's)."""
    xs = np.arange(-length / 2, length / 2 + 1e-9, spacing)
    rings = []
    for i, x in enumerate(xs):
        ang = np.linspace(0, 2 * np.pi, around, endpoint=False) + (i % 2) * np.pi / around
        r = radius_at(x)
        rings.append(np.stack([np.full(around, x), r * np.cos(ang), r * np.sin(ang)], axis=1))
    return np.concatenate(rings)


def _clot_in_tube(rng, *, radius=1.0, centre=(0.0, 0.0, 0.0), n_clot=40, sigma=0.2, speed=0.05,
                  accel=0.0, n_pad=4):
    """Three frames of a ball of ``n_clot`` clot nodes about ``centre`` (in the middle frame)
    moving along x in a straight tube of ``radius`` (``radius`` may be a function of x):
    ``speed`` per frame into the middle frame, ``speed + accel`` out of it; ``n_pad`` padded
    clot nodes far away last. Returns ``(frames [3, N, 3], node_type, mask)`` numpy arrays."""
    wall = _tube(radius if callable(radius) else (lambda _: radius))
    clot = rng.normal(size=(n_clot, 3)) * sigma + np.asarray(centre)
    x = np.concatenate([wall, clot, np.full((n_pad, 3), 40.0)]).astype(np.float32)
    nt = np.array([NodeType.VESSEL] * len(wall) + [NodeType.CLOT] * (n_clot + n_pad), np.int32)
    mask = np.arange(len(x)) < len(wall) + n_clot
    moving = (nt == NodeType.CLOT) & mask
    out = np.repeat(x[None], 3, axis=0)
    out[:, moving, 0] += np.array([-speed, 0.0, speed + accel], np.float32)[:, None]
    return out, nt, mask


def _width(x, nt, mask, scale=1.0):
    out = np.asarray(clot_section_features(jnp.asarray(x), nt, mask, scale=scale))
    clot = (nt == NodeType.CLOT) & mask
    assert np.all(out[~clot] == 0.0)  # vessel and padded nodes
    assert np.ptp(out[clot, 0]) == 0.0  # one clot-wide figure
    return float(out[clot, 0][0])


def test_section_width_is_the_tube_radius_wherever_the_clot_sits_across_it():
    """A tube of radius 1: the width is 1 (within the mesh's sampling) with the clot in the
    middle and 0.5 r off it, where the clearance (the centroid's distance to the nearest wall
    node) falls by half: the width does not read the clot's drift across the vessel."""
    rng = np.random.default_rng(0)
    centred, nt, mask = _clot_in_tube(rng)
    drifted, _, _ = _clot_in_tube(np.random.default_rng(0), centre=(0.0, 0.5, 0.0))
    w_mid, w_off = _width(centred[1], nt, mask), _width(drifted[1], nt, mask)
    assert w_mid == pytest.approx(1.0, abs=0.02)
    assert w_off == pytest.approx(w_mid, abs=0.02)
    clot = (nt == NodeType.CLOT) & mask

    def clear(x):
        return float(np.asarray(clot_clearance(jnp.asarray(x), nt, mask, scale=1.0))[clot, 0][0])

    assert clear(drifted[1]) < 0.6 * clear(centred[1])
    # the scale divides it
    assert _width(centred[1], nt, mask, scale=0.5) == pytest.approx(2 * w_mid, rel=0.05)
    with pytest.raises(ValueError, match="scale"):
        clot_section_features(jnp.asarray(centred[1]), nt, mask, scale=0.0)


def test_section_width_follows_a_tapering_tube_and_is_zero_where_undefined():
    """A tube narrowing from radius 1.3 to 0.9 along x: the width read at the clot is the
    local radius (within 3 %), smaller where the clot stands further along; no clot node, or no
    vessel node within reach: zeros, not a width of nowhere."""
    def taper(x):
        return 1.1 - 0.05 * x

    widths = []
    for cx in (-2.0, 0.0, 2.0):
        frames, nt, mask = _clot_in_tube(np.random.default_rng(1), radius=taper, centre=(cx, 0, 0))
        widths.append(_width(frames[1], nt, mask))
        assert widths[-1] == pytest.approx(taper(cx), rel=0.03)
    assert widths[0] > widths[1] > widths[2]
    x = jnp.asarray(frames[1])
    assert np.all(np.asarray(clot_section_features(x, nt, mask & (nt != NodeType.CLOT),
                                                   scale=1.0)) == 0.0)
    far = np.asarray(frames[1]).copy()
    far[(nt == NodeType.CLOT)] += 100.0  # the clot far from every vessel node
    assert np.all(np.asarray(clot_section_features(jnp.asarray(far), nt, mask, scale=1.0)) == 0.0)
    width, axis, ok = section_width(x, jnp.asarray((nt == NodeType.VESSEL) & mask),
                                    jnp.zeros(3), unit=1.0)
    assert bool(ok) and abs(float(axis[0])) == pytest.approx(1.0, abs=1e-3)  # along the tube


def test_section_width_is_invariant_to_rotations_and_translations():
    frames, nt, mask = _clot_in_tube(np.random.default_rng(2), centre=(0.3, -0.2, 0.1))
    x = frames[1]
    shift = np.array([3.0, -7.0, 2.0], np.float32)
    assert _width(x @ ROT.T + shift, nt, mask) == pytest.approx(_width(x, nt, mask), abs=2e-5)


def test_section_width_reaches_the_model_and_the_training_config():
    """A step with ``section_radius`` reads 1 more input per node, this feature; a negative
    length is refused by the step and by the training options."""
    from dataset_factory import check_step_input_option

    frames, nt, mask = _clot_in_tube(np.random.default_rng(3), n_clot=24)
    prev, cur = jnp.asarray(frames[0]), jnp.asarray(frames[1])
    check_step_input_option(prev, cur, nt, mask, "section_radius", 0.5, SECTION_FEATURES,
                            clot_section_features(cur, nt, mask, scale=0.5),
                            "section_features", atol=1e-6)


def test_section_width_lets_a_step_see_the_width_that_sets_the_speed():
    """Fails without the feature: the tube wall that sets each clot's acceleration is out of the
    graph's reach, so the tiny step learns the mean (error about 2/3 of the spread); given the
    width it tells the three tubes apart (:func:`dataset_factory.width_speed_error`)."""
    from dataset_factory import width_speed_error

    def window(rng, radius, accel):
        return _clot_in_tube(rng, radius=radius, accel=accel, sigma=0.25)

    without = width_speed_error(window, "section_radius", 0.0)
    with_it = width_speed_error(window, "section_radius", 1.0)
    assert without > 0.5
    assert with_it < 0.3 * without
