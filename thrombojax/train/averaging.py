"""Weight averaging: the model as the running mean of the weights over the tail of a training.

``thrombojax train --average-weights SHARE`` (``TrainConfig.average_weights``) keeps, beside the
optimiser's weights, their plain mean over the last ``round(SHARE x steps)`` optimiser steps
(stochastic weight averaging, Izmailov et al. 2018, "Averaging weights leads to wider optima and
better generalization", here over the tail of the cosine decay) in ``TrainState.average``; the
jitted training step (:func:`thrombojax.train.step.make_train_step`) updates it after every step,
and checkpoints, validation and every consumer of a run read it as the model
(:mod:`thrombojax.train.state`). What it did to rollouts: ``docs/rollouts.md``.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

__all__ = ["average_weights"]


def average_weights(average: Any, params: Any, steps_done: jax.Array, average_from: int) -> Any:
    """The running mean of the weights after a step (stochastic weight averaging, Izmailov et
    al. 2018, here over the tail of the cosine decay). Jittable.

    Args:
        average: the mean so far; params: the weights after the step.
        steps_done: optimiser steps done, this one included.
        average_from: steps done before the first averaged one.
    Returns:
        ``params`` itself up to step ``average_from + 1``, then ``average + (params - average) /
        n`` with ``n = steps_done - average_from`` the steps averaged: the plain mean of the
        weights after each of those steps.
    """
    n = steps_done - average_from
    return jax.tree.map(
        lambda a, p: jnp.where(n <= 1, p, a + (p - a) / jnp.maximum(n, 1).astype(a.dtype)),
        average, params)
