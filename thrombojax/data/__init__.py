"""Data preparation: scaling to [-1, 1], splits by simulation, sample windows, augmentation,
node subsets and padded batches."""

from thrombojax.data.augment import subsample_indices
from thrombojax.data.scaling import Scaling, fit_scaling
from thrombojax.data.splits import Split, make_split, split_simulations
from thrombojax.data.windows import window_times

__all__ = [
    "Scaling",
    "Split",
    "fit_scaling",
    "make_split",
    "split_simulations",
    "subsample_indices",
    "window_times",
]
