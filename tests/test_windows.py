"""Sample windows (s_{t-1}, s_t, s_{t+1}): valid times, skip, indexing, partial reads."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import write_good

from thrombojax.data.windows import (
    WindowIndex,
    get_window,
    make_windows,
    read_window,
    window_times,
)
from thrombojax.errors import ConfigError
from thrombojax.io.hdf5 import open_dataset


def test_window_times():
    np.testing.assert_array_equal(window_times(5), [1, 2, 3])
    np.testing.assert_array_equal(window_times(5, skip=2), [2, 3])
    np.testing.assert_array_equal(window_times(41, skip=5), np.arange(5, 40))
    assert window_times(2).size == 0 and window_times(0).size == 0
    assert window_times(5, skip=10).size == 0
    with pytest.raises(ConfigError):
        window_times(5, skip=-1)


def test_make_windows_and_index(tmp_path):
    ds = open_dataset(write_good(tmp_path / "d.h5", n_sims=2))  # 5 frames each
    rows = make_windows(ds, ["sim_1", "sim_0"], skip=2)
    np.testing.assert_array_equal(rows, [[0, 2], [0, 3], [1, 2], [1, 3]])
    assert make_windows({"a": 4, "b": np.zeros((6, 2, 3))}, ["a", "b"]).shape == (2 + 4, 2)
    assert make_windows(ds, []).shape == (0, 2)
    idx = WindowIndex.build(ds, ds.names)
    assert len(idx) == 6 and idx[4] == ("sim_1", 2)
    assert idx.counts() == {"sim_0": 3, "sim_1": 3}


def test_get_window_numpy_jax_and_file(tmp_path):
    ds = open_dataset(write_good(tmp_path / "d.h5", n_sims=1))
    pos = ds.positions("sim_0")
    prev, cur, nxt = get_window(pos, 2)
    np.testing.assert_array_equal(np.stack([prev, cur, nxt]), pos[1:4])
    for got, want in zip(read_window(ds, "sim_0", 3), pos[2:5], strict=True):
        np.testing.assert_array_equal(got, want)
    out = jax.jit(lambda p, t: get_window(p, t))(jnp.asarray(pos), jnp.int32(3))
    np.testing.assert_array_equal(np.stack(out), pos[2:5])
    for bad in (0, 4):
        with pytest.raises(ConfigError):
            get_window(pos, bad)
        with pytest.raises(ConfigError):
            read_window(ds, "sim_0", bad)
