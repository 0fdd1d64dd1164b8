"""Training samples: windows (s_{t-1}, s_t, ..., s_{t+W-2}) of one simulation.

A window of ``W >= 3`` frames is addressed by (simulation index, t), t its second frame (the
"current" frame of the first step), with ``1 <= t <= T - W + 1`` and ``t >= skip``, where
``skip`` is the number of leading frames left out (the dataset records its own, see
:func:`thrombojax.study.skip_frames`). ``W = 3`` is the single-step sample (s_{t-1}, s_t, s_{t+1});
a k-step unrolled loss needs ``W = k + 2`` (``P + k + H + 1`` with ``P`` push-forward steps and a
step reading ``H`` previous frames, whose current frame is then the window's frame ``H``).
Windows are slices of the stored trajectories
(:func:`thrombojax.data.batching.make_batch`), never copies held per window.
"""

from __future__ import annotations

import numpy as np

from thrombojax.errors import ConfigError

__all__ = ["window_times", "start_pair"]


def window_times(n_frames: int, *, skip: int = 0, length: int = 3) -> np.ndarray:
    """Valid frames t (the second frame of each window) of one simulation.

    Args:
        n_frames: T, stored frames.
        skip: leading frames to leave out (t >= skip), >= 0.
        length: W, frames per window, >= 3.
    Returns:
        ``[n_windows]`` int64, ``max(1, skip) .. T - W + 1`` (empty when T < W).
    """
    if skip < 0:
        raise ConfigError(f"windows: skip={skip} must be >= 0")
    if n_frames < 0:
        raise ConfigError(f"windows: n_frames={n_frames} must be >= 0")
    if length < 3:
        raise ConfigError(f"windows: length={length} must be >= 3 frames")
    return np.arange(max(1, skip), max(n_frames - length + 2, 0), dtype=np.int64)


def start_pair(t, start=None, span: int = 1):
    """The two frames ``(max(c - span, 0), c)`` a learned step's start speed is measured
    between, for frame(s) ``t >= 1`` (int or int array): ``c = min(t, start)`` (``start`` None:
    ``c = t``, a rollout from ``t``), frames before 0 being frame 0, the clot at rest
    (:mod:`thrombojax.simulator.start_speed`)."""
    c = np.asarray(t) if start is None else np.minimum(t, max(int(start), 1))
    return np.maximum(c - int(span), 0), c
