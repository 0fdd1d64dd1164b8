"""Training samples: windows (s_{t-1}, s_t, s_{t+1}) of one simulation.

A sample is addressed by (simulation index, t) with ``1 <= t <= T - 2`` and ``t >= skip``, where
``skip`` is the number of leading frames left out (the study skips the first 5 frames of
BendVessel and 40 of ClotEntry in rollouts, where the clot is still settling).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from thrombojax.errors import ConfigError

__all__ = ["window_times", "make_windows", "WindowIndex", "get_window", "read_window"]


def window_times(n_frames: int, *, skip: int = 0) -> np.ndarray:
    """Valid centre frames t of one simulation.

    Args:
        n_frames: T, stored frames.
        skip: leading frames to leave out (t >= skip), >= 0.
    Returns:
        ``[n_windows]`` int64, ``max(1, skip) .. T - 2`` (empty when T < 3).
    """
    if skip < 0:
        raise ConfigError(f"windows: skip={skip} must be >= 0")
    if n_frames < 0:
        raise ConfigError(f"windows: n_frames={n_frames} must be >= 0")
    return np.arange(max(1, skip), max(n_frames - 1, 0), dtype=np.int64)


def _n_frames(source: Any, name: str) -> int:
    if hasattr(source, "n_frames") and callable(source.n_frames):
        return int(source.n_frames(name))
    value = source[name]
    return int(value) if np.ndim(value) == 0 else int(np.shape(value)[0])


def make_windows(source: Any, names: Sequence[str], *, skip: int = 0) -> np.ndarray:
    """All windows of the given simulations.

    Args:
        source: a :class:`~thrombojax.io.hdf5.Dataset` (frame counts from metadata) or a mapping
            name -> frame count or name -> ``[T, N, 3]`` positions.
        names: simulations to use; row ``[i, t]`` refers to ``names[i]``.
        skip: leading frames to leave out.
    Returns:
        ``[n_windows, 2]`` int64 rows (simulation index, t), simulation-major.
    """
    rows = [
        np.stack([np.full(len(ts), i, np.int64), ts], axis=1)
        for i, ts in enumerate(window_times(_n_frames(source, n), skip=skip) for n in names)
    ]
    return np.concatenate(rows) if rows else np.zeros((0, 2), np.int64)


@dataclasses.dataclass(frozen=True)
class WindowIndex:
    """The windows of a set of simulations, addressable by a flat sample index.

    Attributes:
        names: simulation names; ``rows[:, 0]`` indexes them.
        rows: ``[n_windows, 2]`` int64 (simulation index, t).
        skip: the leading frames left out.
    """

    names: tuple[str, ...]
    rows: np.ndarray
    skip: int = 0

    @classmethod
    def build(cls, source: Any, names: Sequence[str], *, skip: int = 0) -> WindowIndex:
        """Index every window of ``names`` in ``source`` (see :func:`make_windows`)."""
        return cls(tuple(names), make_windows(source, names, skip=skip), skip)

    def __len__(self) -> int:
        return int(self.rows.shape[0])

    def __getitem__(self, i: int) -> tuple[str, int]:
        """``(simulation name, t)`` of sample ``i``."""
        sim, t = self.rows[i]
        return self.names[int(sim)], int(t)

    def counts(self) -> Mapping[str, int]:
        """Number of windows per simulation."""
        counts = np.bincount(self.rows[:, 0], minlength=len(self.names))
        return {n: int(c) for n, c in zip(self.names, counts, strict=True)}


def get_window(positions: Any, t: Any) -> tuple[Any, Any, Any]:
    """Frames (t-1, t, t+1) of one trajectory.

    Args:
        positions: ``[T, N, 3]`` numpy or jax array.
        t: centre frame; a Python / numpy int is bounds-checked, a traced jax int is not
            (jax clamps out-of-range indices).
    Returns:
        ``(prev, cur, next)``, each ``[N, 3]``.
    """
    if isinstance(t, int | np.integer):
        n_frames = positions.shape[0]
        if not 1 <= int(t) <= n_frames - 2:
            msg = f"windows: t={int(t)} outside [1, {n_frames - 2}] for {n_frames} frames"
            raise ConfigError(msg)
    return positions[t - 1], positions[t], positions[t + 1]


def read_window(dataset: Any, name: str, t: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read only frames (t-1, t, t+1) of one simulation from a dataset file.

    Returns:
        ``(prev, cur, next)``, each ``[N, 3]`` float32.
    """
    n_frames = dataset.n_frames(name)
    if not 1 <= int(t) <= n_frames - 2:
        raise ConfigError(f"windows: t={int(t)} outside [1, {n_frames - 2}] for '{name}'")
    frames = dataset.positions(name, slice(int(t) - 1, int(t) + 2))
    return frames[0], frames[1], frames[2]
