"""Data preparation: scaling to [-1, 1], splits by simulation, sample windows."""

from thrombojax.data.scaling import Scaling, fit_scaling
from thrombojax.data.splits import Split, make_split, split_simulations
from thrombojax.data.windows import (
    WindowIndex,
    get_window,
    make_windows,
    read_window,
    window_times,
)

__all__ = [
    "Scaling",
    "Split",
    "WindowIndex",
    "fit_scaling",
    "get_window",
    "make_split",
    "make_windows",
    "read_window",
    "split_simulations",
    "window_times",
]
