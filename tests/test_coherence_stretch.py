"""Coherence whose copy of the rest shape may stretch (``max_stretch``): a clot that shortens and
widens without a change of volume (as BendVessel's true clot does when it leaves the vessel) is
left alone within the bound and brought back to the bound beyond it; a change of volume is
corrected as by the rigid copy."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from wall_factory import clot_cloud

from thrombojax.errors import ConfigError
from thrombojax.simulator.guards import coherence


def _turn(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], np.float32)


def _deformed(ref, mask, stretch_x: float, *, volume: bool = True, angle: float = 0.4):
    """The clot stretched by ``stretch_x`` along x (and by ``stretch_x ** -0.5`` across it when
    ``volume``, else not at all), turned about z and moved; padded rows kept."""
    across = stretch_x ** -0.5 if volume else 1.0
    x = ref.copy()
    c = ref[mask].mean(axis=0)
    x[mask] = ((ref[mask] - c) * [stretch_x, across, across]) @ _turn(angle).T + c + [1.0, 0.5, 0]
    return x


def _guard(x, ref, mask, max_stretch):
    f = jax.jit(lambda a, ms: coherence(a, jnp.asarray(ref), jnp.asarray(mask), stiffness=1.0,
                                        tolerance=0.0, max_stretch=ms))
    out, corr = f(jnp.asarray(x), max_stretch)
    return np.asarray(out), np.asarray(corr)


def _extent(x, mask, axis):
    """The clot's spread (std) along ``axis`` (a unit vector)."""
    return float(np.std(np.asarray(x)[mask] @ axis))


def test_a_volume_preserving_stretch_within_the_bound_is_left_alone():
    ref, mask = clot_cloud()
    x = _deformed(ref, mask, 0.85)  # shorter along its length, wider across, as in the exit
    rigid_out, rigid_corr = _guard(x, ref, mask, None)
    out, corr = _guard(x, ref, mask, 1.2)
    assert rigid_corr[mask].max() > 0.1  # the rigid copy pulls it back toward its rest shape
    assert corr.max() < 1e-4, corr.max()
    np.testing.assert_allclose(out, x, atol=1e-4)
    # max_stretch 1: a rigid copy again (its rotation from the affine fit, not the rigid fit)
    def pairwise(y):
        return np.linalg.norm(y[mask][:, None] - y[mask][None], axis=-1)

    for snapped in (rigid_out, _guard(x, ref, mask, 1.0)[0]):
        np.testing.assert_allclose(pairwise(snapped), pairwise(ref), atol=1e-4)


def test_a_stretch_beyond_the_bound_is_brought_back_to_the_bound():
    ref, mask = clot_cloud()
    x = _deformed(ref, mask, 1.5)
    out, corr = _guard(x, ref, mask, 1.2)
    along = _turn(0.4)[:, 0]
    ratio = _extent(out, mask, along) / _extent(ref, mask, np.array([1.0, 0.0, 0.0]))
    assert corr[mask].max() > 0.05
    assert ratio == pytest.approx(1.2, abs=0.01)  # the rigid copy would give 1.0
    np.testing.assert_array_equal(out[~mask], x[~mask])
    np.testing.assert_array_equal(corr[~mask], 0.0)


def test_a_change_of_volume_is_corrected():
    ref, mask = clot_cloud()
    x = _deformed(ref, mask, 1.15, volume=False)  # longer, not narrower: the volume grows
    out, corr = _guard(x, ref, mask, 1.2)
    along = _turn(0.4)[:, 0]
    ratio = _extent(out, mask, along) / _extent(ref, mask, np.array([1.0, 0.0, 0.0]))
    assert corr[mask].max() > 0.02
    assert ratio < 1.12  # the 15 % stretch is shared out to keep the volume: 1.15 ** (2 / 3)


def test_build_guards_passes_max_stretch_and_checks_it():
    from wall_factory import straight_tube

    from thrombojax.simulator.guard_set import build_guards
    from thrombojax.types import NodeType

    x0, node_type = straight_tube()
    clot = node_type == NodeType.CLOT
    x = _deformed(x0, clot, 0.9, angle=0.0)
    moved = {}
    for ms in (None, 1.2):
        guards = build_guards(x0, node_type, x0, node_type, radius=1.0, containment=False,
                              tolerance_r=0.0, max_stretch=ms)
        assert guards.stretching is (ms is not None)
        _, corr = jax.jit(guards.apply)(jnp.asarray(x))
        moved[ms] = float(np.asarray(corr["coherence"]).max())
    assert moved[None] > 0.02 and moved[1.2] < 1e-4, moved
    with pytest.raises(ConfigError, match="max_stretch"):
        build_guards(x0, node_type, x0, node_type, radius=1.0, max_stretch=0.9)


def test_fit_coherence_measures_with_the_stretching_copy():
    from thrombojax.eval.coherence_fit import clot_deviations
    from thrombojax.types import NodeType

    ref, mask = clot_cloud(n_pad=0)
    frames = np.stack([_deformed(ref, mask, s, angle=0.0) for s in (1.0, 0.95, 0.9, 0.85)])
    node_type = np.full(ref.shape[0], NodeType.CLOT)
    rigid = clot_deviations(frames, node_type, 0, 1.0)
    bent = clot_deviations(frames, node_type, 0, 1.0, max_stretch=1.2)
    assert rigid.shape == bent.shape == (3, ref.shape[0])
    assert rigid.max() > 0.1 and bent.max() < 1e-4
