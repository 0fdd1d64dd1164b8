"""The centroid error split along and across the true track (thrombojax.eval.track)."""

import numpy as np
import pytest

from thrombojax.eval.track import size_ratio, track_errors

CLOT = np.array([True, True, True, True, False])


def _clot_at(centres: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """Frames whose four clot nodes sit about ``centres`` (a fifth, wall node stays put)."""
    shape = scale * np.array([[0.1, 0, 0], [-0.1, 0, 0], [0, 0.2, 0], [0, -0.2, 0]])
    clot = centres[:, None] + shape[None]
    wall = np.broadcast_to(np.array([5.0, 5.0, 5.0]), (len(centres), 1, 3))
    return np.concatenate([clot, wall], axis=1)


def _line(n: int = 20, speed: float = 0.3) -> np.ndarray:
    return np.stack([speed * np.arange(1, n + 1), np.zeros(n), np.zeros(n)], axis=1)


def test_a_clot_ahead_on_the_track_is_along_not_across():
    c = _line()
    along, across = track_errors(_clot_at(c + [0.45, 0, 0]), _clot_at(c), CLOT)
    np.testing.assert_allclose(along, 0.45, atol=1e-9)
    np.testing.assert_allclose(across, 0.0, atol=1e-9)


def test_a_clot_beside_the_track_is_across_not_along():
    c = _line()
    along, across = track_errors(_clot_at(c + [0, 0, 0.3]), _clot_at(c), CLOT)
    np.testing.assert_allclose(along, 0.0, atol=1e-9)
    np.testing.assert_allclose(across, 0.3, atol=1e-9)


def test_along_is_arc_length_on_a_bent_track_and_extends_past_both_ends():
    theta = np.linspace(0.0, np.pi, 61)  # a half circle of radius 4: arc 4 * dtheta per frame
    c = 4.0 * np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=1)
    lag = 5  # the prediction is 5 frames behind: along = -5 chords
    chord = np.linalg.norm(c[1] - c[0])
    pred = np.concatenate([np.repeat(c[:1], lag, axis=0), c[:-lag]])
    along, _ = track_errors(_clot_at(pred), _clot_at(c), CLOT)
    np.testing.assert_allclose(along[lag:], -lag * chord, rtol=1e-9)
    # a clot beyond the last true frame, on the tangent: ahead by its distance
    tangent = (c[-1] - c[-2]) / chord
    beyond = c.copy()
    beyond[-1] = c[-1] + 0.7 * tangent
    along, across = track_errors(_clot_at(beyond), _clot_at(c), CLOT)
    assert along[-1] == pytest.approx(0.7)
    assert across[-1] == pytest.approx(0.0, abs=1e-9)
    # behind the start frame, with the start given: negative along, measured on the first segment
    before = c[1:].copy()
    before[0] = c[0] - 0.2 * (c[1] - c[0]) / chord
    along, _ = track_errors(_clot_at(before), _clot_at(c[1:]), CLOT, start=_clot_at(c[:1])[0])
    assert along[0] == pytest.approx(-(chord + 0.2))


def test_size_ratio_sees_a_stretched_clot_but_not_a_moved_one():
    c = _line(5)
    np.testing.assert_allclose(size_ratio(_clot_at(c, 1.2), _clot_at(c), CLOT), 1.2)
    np.testing.assert_allclose(size_ratio(_clot_at(c + 3.0), _clot_at(c), CLOT), 1.0)


def test_bad_shapes_are_errors():
    c = _line(5)
    with pytest.raises(ValueError, match="same"):
        track_errors(_clot_at(c)[:4], _clot_at(c), CLOT)
    with pytest.raises(ValueError, match="no node"):
        track_errors(_clot_at(c), _clot_at(c), np.zeros(5, bool))
