"""Masked losses over the real clot nodes of one window (the vessel is rigid, never predicted).

Two numbers per window, both averaged over the clot nodes, the predicted steps and x, y, z:

* ``loss``: the training objective, the MSE of the model output against the *normalised*
  acceleration ``TargetStats.normalize(s_{t+1} - 2 s_t + s_{t-1})``: every axis has unit
  variance, so the loss scale does not depend on the dataset's time step (MeshGraphNets /
  learning-to-simulate convention), in the learned step's frame
  (:meth:`thrombojax.simulator.step.LearnedStep.normalized_target`).
* ``mse``: the study's metric, the MSE of the integrated prediction of s_{t+1} against the true
  s_{t+1} in scaled [-1, 1] coordinates. For one step it equals the loss weighted by ``std**2``
  per axis, so both have the same minimiser; ``mse`` is what the study's table reports and what
  selects the best checkpoint.

With ``k > 1`` steps (the k-step unrolled loss) the learned step is applied ``k`` times from
``(s_{t-1}, s_t)`` with its own predictions fed back (:func:`thrombojax.simulator.rollout.unroll`,
gradients through every step). The target of step ``j`` is the acceleration that would bring the
rollout back onto the true frame ``s_{t+j+1}`` from where the rollout stands, so ``k = 1`` is
exactly the single-step loss.

Push-forward training (Brandstetter, Worrall and Welling 2022, "Message passing neural PDE
solvers"): with ``pushforward = p > 0`` the step is first applied ``p`` times from
``(s_{t-1}, s_t)`` *without* gradients, and the loss steps start from the model's own prediction
``(s^_{t+p-1}, s^_{t+p})``; the model learns to correct the input distribution it creates in a
rollout, at the cost of one forward pass per pushed step. With ``push_guards``
(:mod:`thrombojax.train.push_guards`) every pushed frame passes through the rollout's coherence
and containment guards first, so the loss starts from the state a guarded rollout is in.

:func:`flat_window_loss_terms` computes the same terms for a whole batch with the model run
once on the batch's flat graph (:mod:`thrombojax.simulator.flat`).

Sums and counts are returned (not means) so a batch, possibly split over devices, pools all its
clot nodes: ``sum(sq) / sum(count)``.

``clot_mean_sum`` is the clot-wide part of the loss's error: the squared error of the clot's
*mean* normalised acceleration (averaged over the steps and x, y, z), times the window's clot
node count so it pools the same way. It is part of ``loss_sum`` already (the mean error is one
component of every node's error); :func:`thrombojax.train.step.batch_loss` can weight it again
(``clot_mean_weight``): a rollout integrates a clot-wide error step after step, while the
guards and the clot's own coherence take out much of an error that differs from node to node.

``wall_sum`` (only with ``wall_term=True``, so no wall search is compiled otherwise): the squared
distance by which the predicted clot nodes lie further through the vessel wall than the true ones
(:mod:`thrombojax.train.wall_loss`), summed over the clot nodes and averaged over the steps;
:func:`thrombojax.train.step.batch_loss` adds it weighted by ``wall_loss_weight``.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from thrombojax.simulator.flat import FlatStep
from thrombojax.simulator.rollout import unroll
from thrombojax.simulator.step import LearnedStep, target_acceleration
from thrombojax.train.push_guards import PushGuards, guarded_push
from thrombojax.train.wall_loss import wall_sum
from thrombojax.types import TargetStats, clot_mask

__all__ = ["window_loss_terms", "flat_window_loss_terms"]


def window_loss_terms(
    step: LearnedStep,
    params: dict,
    stats: TargetStats,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    k: int = 1,
    pushforward: int = 0,
    train: bool,
    rng: jax.Array | None,
    wall_term: bool = False,
    rest: jax.Array | None = None,
    push_guards: PushGuards | None = None,
) -> dict[str, jax.Array]:
    """Run the learned step on one window and return summed squared errors over its clot nodes.

    Args:
        step: the learned simulator (:func:`thrombojax.simulator.step.make_step`).
        params: the surrogate's variables. stats: acceleration normalisation statistics.
        frames: ``[W, n_nodes, 3]`` (s_{t-H}, ..., s_t, ..., s_{t+W-H-1}) scaled, ``H`` the
            step's ``history`` (1: the window starts at s_{t-1}),
            ``W >= pushforward + k + H + 1`` (later frames are not used).
        node_type: ``[n_nodes]`` NodeType. mask: ``[n_nodes]`` real nodes.
        k: steps unrolled with gradients (static, >= 1).
        pushforward: steps applied first without gradients (static, >= 0).
        train: model in training mode (dropout); rng: its PRNG key.
        wall_term: also return ``wall_sum``, the predictions' squared excess through the wall
            (:mod:`thrombojax.train.wall_loss`; static: off, no wall search is compiled).
        rest: ``[n_nodes, 3]`` the clot's rest state (the simulation's first frame), which a
            step with ``rest_edges`` reads (required then: a window starts later), and the
            push-forward guards' coherence holds the clot to; for a step with ``start_speed``, the
            window's lead frames ``[L, n_nodes, 3]`` (the rest frame, then the start frames).
        push_guards: guard every push-forward step's prediction before the next step reads it
            (:mod:`thrombojax.train.push_guards`; static; needs ``pushforward >= 1`` and
            ``rest``). ``None``: the plain push-forward.
    Returns:
        ``{"loss_sum", "mse_sum", "clot_mean_sum", "count"}`` (and ``"wall_sum"``): squared
        errors summed over clot nodes and averaged over steps and x, y, z; the clot-wide part
        (module docstring); the number of clot nodes.
    """
    frames, positions, outputs = _predict(step, params, stats, frames, node_type, mask, k=k,
                                          pushforward=pushforward, train=train, rng=rng,
                                          rest=rest, push_guards=push_guards)
    return _terms(step, stats, frames, node_type, mask, positions, outputs, wall_term)


def flat_window_loss_terms(
    step: FlatStep,
    params: dict,
    stats: TargetStats,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    k: int = 1,
    pushforward: int = 0,
    train: bool,
    rng: jax.Array | None,
    wall_term: bool = False,
) -> dict[str, jax.Array]:
    """:func:`window_loss_terms` of every window of a batch, the model run on the flat graph.

    Args:
        step: the flat-batch step (:class:`thrombojax.simulator.flat.FlatStep`).
        frames: ``[B, W, n_nodes, 3]``; node_type, mask: ``[B, n_nodes]``.
        params, stats, k, pushforward, train, wall_term: as :func:`window_loss_terms`.
        rng: one dropout key for the whole batch.
    Returns:
        The terms of every window, each ``[B]`` (what ``jax.vmap(window_loss_terms)`` returns).
    """
    frames = jnp.moveaxis(frames, 1, 0)  # [W, B, N, 3]: the step maps [B, N, 3] frames
    frames, positions, outputs = _predict(step, params, stats, frames, node_type, mask, k=k,
                                          pushforward=pushforward, train=train, rng=rng)
    per_window = functools.partial(_terms, step.step, stats, wall_term=wall_term)
    return jax.vmap(per_window, in_axes=(1, 0, 0, 1, 1))(frames, node_type, mask, positions,
                                                         outputs)


def _predict(step, params, stats, frames, node_type, mask, *, k, pushforward, train, rng,
             rest=None, push_guards=None):
    """The window's first ``H + k + 1`` frames after the push-forward steps (``H`` the step's
    history: 1 for one velocity), and the ``k`` predicted positions and outputs (``[k, ...]``);
    frames lead with the window axis ``W``; ``rest``: the rest frame (``rest_edges``)."""
    step.require_dense("the training loss")
    h = step.history
    if (getattr(step, "rest_edges", False) or getattr(step, "start_speed", False)) and rest is None:
        raise ValueError("the step reads the rest state or the clot's start speed: a training "
                         "window needs its lead frames")

    need = pushforward + k + h + 1
    if k < 1 or pushforward < 0 or frames.shape[0] < need:
        raise ValueError(f"k = {k} loss steps after {pushforward} push-forward steps with "
                         f"{h} previous frame(s) need a window of >= {need} frames, got "
                         f"{frames.shape[0]}")
    if push_guards is not None and (not pushforward or rest is None):
        raise ValueError("push-forward guards need push-forward steps (pushforward >= 1) and the "
                         "window's rest frame")
    if push_guards is not None:
        pushed = guarded_push(step, params, stats, frames, rest, node_type, mask, pushforward,
                              push_guards, train=train,
                              rng=None if rng is None else jax.random.fold_in(rng, 10_007))
    elif pushforward:
        pushed, _ = unroll(step, params, stats, step.previous(frames, h, rest), frames[h],
                           node_type, mask, pushforward, train=train,
                           rng=None if rng is None else jax.random.fold_in(rng, 10_007))
    if pushforward:
        pushed = jax.lax.stop_gradient(pushed)
        start = jnp.concatenate([frames[:h + 1], pushed])[-(h + 1):]
        frames = jnp.concatenate([start, frames[pushforward + h + 1:need]])
    frames = frames[:k + h + 1]
    if k == 1:
        out = step(params, stats, step.previous(frames, h, rest), frames[h], node_type, mask,
                   train=train, rng=rng)
        return frames, out.positions[None], out.output[None]
    positions, outputs = unroll(step, params, stats, step.previous(frames, h, rest), frames[h],
                                node_type, mask, k, train=train, rng=rng)
    return frames, positions, outputs


def _terms(step, stats, frames, node_type, mask, positions, outputs, wall_term=False):
    """The loss terms of one window from its ``H + k + 1`` frames and ``k`` predictions."""
    k, h = positions.shape[0], step.history
    states = jnp.concatenate([frames[:h + 1], positions[:-1]])  # s_{t-h}, ..., s^_{t+k-1}
    truth = frames[h + 1:h + 1 + k]
    last, cur = states[h - 1:h - 1 + k], states[h:h + k]
    # the step's prior (0 without one); a loop over the k (static, small) steps, not a vmap:
    # the prior's eigendecompositions vmapped here hung inside XLA on BendVessel (CPU, jax
    # 0.10.2). With k = 1 XLA merges it with the step's own (same inputs: one computation).
    prior = 0.0 if step.prior_radius <= 0 else jnp.stack(
        [step.prior(last[i], cur[i], node_type, mask) for i in range(k)])
    target = step.normalized_target(  # the model learns what the step's prior leaves
        stats, target_acceleration(last, cur, truth) - prior, frames[h], node_type, mask)
    clot = clot_mask(node_type, mask)[None, :, None]
    err = jnp.where(clot, outputs - target, 0.0)
    loss_sq = (err ** 2).mean(axis=(0, 2))
    mse_sq = jnp.where(clot, (positions - truth) ** 2, 0.0).mean(axis=(0, 2))
    count = clot[0, :, 0].sum().astype(jnp.float32)
    mean_err = err.sum(axis=1) / jnp.maximum(count, 1.0)  # [k, 3]: the clot-wide error
    terms = {
        "loss_sum": loss_sq.sum(),
        "mse_sum": mse_sq.sum(),
        "clot_mean_sum": count * (mean_err ** 2).mean(),
        "count": count,
    }
    if wall_term:
        terms["wall_sum"] = wall_sum(positions, truth, node_type, mask, stats)
    return terms
