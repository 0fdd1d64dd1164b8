"""Masked losses over the real clot nodes of one window (the vessel is rigid, never predicted).

Two numbers per window, both averaged over the clot nodes, the predicted steps and x, y, z:

* ``loss``: the training objective, the MSE of the model output against the *normalised*
  acceleration ``TargetStats.normalize(s_{t+1} - 2 s_t + s_{t-1})``: every axis has unit
  variance, so the loss scale does not depend on the dataset's time step (MeshGraphNets /
  learning-to-simulate convention).
* ``mse``: the study's metric, the MSE of the integrated prediction of s_{t+1} against the true
  s_{t+1} in scaled [-1, 1] coordinates. For one step it equals the loss weighted by ``std**2``
  per axis, so both have the same minimiser; ``mse`` is what the study's table reports and what
  selects the best checkpoint.

With ``k > 1`` steps (the k-step unrolled loss) the learned step is applied ``k`` times from
``(s_{t-1}, s_t)`` with its own predictions fed back (:func:`thrombojax.simulator.rollout.unroll`,
gradients through every step). The target of step ``j`` is the acceleration that would bring the
rollout back onto the true frame ``s_{t+j+1}`` from where the rollout stands, so ``k = 1`` is
exactly the single-step loss.

Sums and counts are returned (not means) so a batch, possibly split over devices, pools all its
clot nodes: ``sum(sq) / sum(count)``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.simulator.rollout import unroll
from thrombojax.simulator.step import LearnedStep, target_acceleration
from thrombojax.types import TargetStats, clot_mask

__all__ = ["window_loss_terms"]


def window_loss_terms(
    step: LearnedStep,
    params: dict,
    stats: TargetStats,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    k: int = 1,
    train: bool,
    rng: jax.Array | None,
) -> dict[str, jax.Array]:
    """Run the learned step on one window and return summed squared errors over its clot nodes.

    Args:
        step: the learned simulator (:func:`thrombojax.simulator.step.make_step`).
        params: the surrogate's variables. stats: acceleration normalisation statistics.
        frames: ``[W, n_nodes, 3]`` (s_{t-1}, s_t, ..., s_{t+W-2}) scaled, ``W >= k + 2``.
        node_type: ``[n_nodes]`` NodeType. mask: ``[n_nodes]`` real nodes.
        k: steps unrolled (static, ``1 <= k <= W - 2``).
        train: model in training mode (dropout); rng: its PRNG key.
    Returns:
        ``{"loss_sum", "mse_sum", "count"}``: squared errors summed over clot nodes and averaged
        over steps and x, y, z; the number of clot nodes.
    """
    if not 1 <= k <= frames.shape[0] - 2:
        raise ValueError(f"k = {k} steps need a window of >= {k + 2} frames, got {frames.shape[0]}")
    if k == 1:
        out = step(params, stats, frames[0], frames[1], node_type, mask, train=train, rng=rng)
        positions, outputs = out.positions[None], out.output[None]
    else:
        positions, outputs = unroll(step, params, stats, frames[0], frames[1], node_type, mask, k,
                                    train=train, rng=rng)
    states = jnp.concatenate([frames[:2], positions[:-1]])  # s_{t-1+j}, j = 0 .. k
    truth = frames[2:2 + k]
    target = stats.normalize(target_acceleration(states[:-1], states[1:], truth))
    clot = clot_mask(node_type, mask)[None, :, None]
    loss_sq = jnp.where(clot, (outputs - target) ** 2, 0.0).mean(axis=(0, 2))
    mse_sq = jnp.where(clot, (positions - truth) ** 2, 0.0).mean(axis=(0, 2))
    return {
        "loss_sum": loss_sq.sum(),
        "mse_sum": mse_sq.sum(),
        "count": clot[0, :, 0].sum().astype(jnp.float32),
    }
