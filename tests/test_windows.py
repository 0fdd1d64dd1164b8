"""Sample windows: valid times, skip, window length."""

from __future__ import annotations

import numpy as np
import pytest

from thrombojax.data.windows import window_times
from thrombojax.errors import ConfigError


def test_window_times():
    np.testing.assert_array_equal(window_times(5), [1, 2, 3])
    np.testing.assert_array_equal(window_times(5, skip=2), [2, 3])
    np.testing.assert_array_equal(window_times(41, skip=5), np.arange(5, 40))
    assert window_times(2).size == 0 and window_times(0).size == 0
    assert window_times(5, skip=10).size == 0
    with pytest.raises(ConfigError):
        window_times(5, skip=-1)


def test_window_times_longer_windows():
    """A window of W frames from t - 1 must end inside the simulation: t + W - 2 <= T - 1."""
    np.testing.assert_array_equal(window_times(6, length=4), [1, 2, 3])
    np.testing.assert_array_equal(window_times(6, length=6), [1])
    assert window_times(6, length=7).size == 0
    with pytest.raises(ConfigError):
        window_times(6, length=2)
