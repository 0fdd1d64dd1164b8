"""All of a training window's input noise in one function, in a fixed order with fixed keys.

:func:`corrupt_window` applies the noises of :mod:`thrombojax.train.noise` and
:mod:`thrombojax.train.shape_noise` that the training step
(:func:`thrombojax.train.step.batch_loss`) switches on, each from its own fold of the window's
key, so switching one on leaves the draws of the others unchanged.
"""

from __future__ import annotations

import jax

from thrombojax.train.noise import (
    add_direction_noise,
    add_history_noise,
    add_speed_noise,
    add_training_noise,
    add_wall_noise,
    time_scale_window,
)
from thrombojax.train.shape_noise import add_stretch_noise, add_swell_noise

__all__ = ["corrupt_window"]


def corrupt_window(key, frames, node_type, mask, *, current, noise_std, noise_gamma,
                   noise_walk, noise_shared, wall_noise, history_noise, speed_noise,
                   speed_noise_steady, direction_noise, swell_noise, stretch_noise, time_scale):
    """One training window with its input noise (:mod:`thrombojax.train.noise`): the time
    scaling first from ``fold_in(key, 4)``, the speed and direction noise (on the clean motion)
    from ``fold_in(key, 3)`` and ``fold_in(key, 5)``, the swell and stretch noise from
    ``fold_in(key, 6)`` and ``fold_in(key, 7)``, then the Gaussian or random-walk noise from
    ``key``, the wall noise from ``fold_in(key, 1)`` and the history noise from
    ``fold_in(key, 2)`` (so turning any on leaves the other draws of a seed unchanged).

    The keyword arguments are :func:`thrombojax.train.step.batch_loss`'s of the same names;
    ``current`` is the index of s_t in ``frames`` (the step's history). A noise at 0 (or
    ``time_scale`` at 1) is not compiled at all.
    """
    if time_scale != 1.0:
        frames = time_scale_window(jax.random.fold_in(key, 4), frames, node_type, mask,
                                   factor=time_scale, current=current)
    if speed_noise > 0:
        frames = add_speed_noise(jax.random.fold_in(key, 3), frames, node_type, mask,
                                 std=speed_noise, current=current, steady=speed_noise_steady)
    if direction_noise > 0:
        frames = add_direction_noise(jax.random.fold_in(key, 5), frames, node_type, mask,
                                     std=direction_noise, current=current)
    if swell_noise > 0:
        frames = add_swell_noise(jax.random.fold_in(key, 6), frames, node_type, mask,
                                 std=swell_noise, current=current)
    if stretch_noise > 0:
        frames = add_stretch_noise(jax.random.fold_in(key, 7), frames, node_type, mask,
                                   std=stretch_noise, current=current)
    if noise_std > 0:
        frames = add_training_noise(key, frames, node_type, mask, std=noise_std,
                                    gamma=noise_gamma, current=current, walk=noise_walk,
                                    shared=noise_shared)
    if wall_noise > 0:
        frames = add_wall_noise(jax.random.fold_in(key, 1), frames, node_type, mask,
                                std=wall_noise, current=current)
    if history_noise > 0:
        frames = add_history_noise(jax.random.fold_in(key, 2), frames, node_type, mask,
                                   std=history_noise, current=current)
    return frames
