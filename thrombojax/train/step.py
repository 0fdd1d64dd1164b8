"""The jitted training and evaluation steps, data parallel over devices with ``jax.sharding``.

``train_step(state, batch, rng) -> (state, metrics)``: per sample (``jax.vmap`` over the windows)
optional training noise, then the learned step of :mod:`thrombojax.simulator.step` once or ``k``
times (:mod:`thrombojax.train.loss`), masked losses pooled over all clot nodes of the batch
(``sum / count``), differentiated and applied with the optax transformation (AdamW, warm-up +
cosine, optional clipping: :mod:`thrombojax.train.schedule`).
``flat_batch=True`` (off by default) runs the model once on the batch as one flat graph instead
of ``vmap`` over the samples (:mod:`thrombojax.simulator.flat`; same loss and gradients, no
faster on the CPU: ``benchmarks/results/flat_batch_cpu.md``).

Data parallelism (:mod:`thrombojax.train.mesh`): :func:`data_mesh` builds a 1-D mesh
``("data",)`` over the local devices (or all devices of all hosts after
``jax.distributed.initialize()``); :func:`shard_batch` places the batch with
``NamedSharding(mesh, P("data"))`` on its leading axis and :func:`replicate` the state with
``P()``. ``jit`` then partitions the step itself (computation follows data): every device runs
the model on its slice of the batch, and the pooled sums become one all-reduce: the loss and
gradients of the whole batch (tested against one device; batch size a multiple of the devices).

Multi-host (a GPU cluster): start the same command on every host, e.g. with SLURM::

    srun --nodes=2 --ntasks-per-node=1 thrombojax train --dataset clotentry.h5 --model erwin \\
        --out runs/erwin --distributed

``--distributed`` calls ``jax.distributed.initialize()`` (coordinator, process count and id from
SLURM / Open MPI / ``JAX_COORDINATOR_ADDRESS`` etc.) first; the mesh spans every device of every
host, each host feeds the same seeded batch, and :func:`shard_batch` keeps its slice.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import optax

from thrombojax.errors import ConfigError
from thrombojax.models.registry import Surrogate
from thrombojax.simulator.flat import FlatStep, flat_batch_ok
from thrombojax.simulator.previous import lead_count
from thrombojax.simulator.start_speed import jitter_start_speed
from thrombojax.simulator.step import LearnedStep, make_step
from thrombojax.train.averaging import average_weights
from thrombojax.train.corrupt import corrupt_window
from thrombojax.train.loss import flat_window_loss_terms, window_loss_terms
from thrombojax.train.mesh import data_mesh, replicate, shard_batch
from thrombojax.train.push_guards import PushGuards, guard_inputs
from thrombojax.train.speedup import speedup_window_weight
from thrombojax.train.state import TrainState
from thrombojax.types import TargetStats
from thrombojax.xla_options import jit as xla_jit

__all__ = [
    "data_mesh",
    "shard_batch",
    "replicate",
    "batch_loss",
    "make_train_step",
    "make_eval_step",
    "init_state",
]


def _as_step(model: Surrogate | LearnedStep) -> LearnedStep:
    return model if isinstance(model, LearnedStep) else make_step(model)


def batch_loss(
    model: Surrogate | LearnedStep,
    params: dict,
    stats: TargetStats,
    batch: Any,
    rng: jax.Array | None,
    *,
    train: bool,
    noise_std: float = 0.0,
    noise_gamma: float = 0.1,
    noise_walk: bool = False,
    noise_shared: float = 0.0,
    wall_noise: float = 0.0,
    history_noise: float = 0.0,
    speed_noise: float = 0.0,
    speed_noise_steady: float = 0.0,
    direction_noise: float = 0.0,
    swell_noise: float = 0.0,
    stretch_noise: float = 0.0,
    time_scale: float = 1.0,
    k: int = 1,
    pushforward: int = 0,
    flat_batch: bool = False,
    clot_mean_weight: float = 0.0,
    wall_loss_weight: float = 0.0,
    speedup_weight: float = 0.0,
    speedup_fraction: float = 0.1,
    push_guards: PushGuards | None = None,
    input_guards: PushGuards | None = None,
    start_speed_noise: float = 0.0,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """Loss of a batch pooled over its clot nodes, and metrics.

    Args:
        model: the surrogate (or its learned step). params, stats: its variables and statistics.
        batch: :class:`thrombojax.data.batching.Batch` (``frames [B, W, N, 3]``,
            ``W >= pushforward + k + H + 1``, ``H`` the step's history; a step with
            ``rest_edges``, ``push_guards`` or ``input_guards`` reads ``[B, 1 + W, N, 3]``,
            the rest frame first: ``make_batch(..., rest=True)``; with ``start_speed`` two
            start frames follow: ``make_batch(..., start_speed=...)``).
        rng: PRNG key for noise and dropout (``None`` in evaluation).
        train: training mode (noise, dropout).
        noise_std, noise_gamma, noise_walk, noise_shared: training noise
            (:mod:`thrombojax.train.noise`; ``noise_walk``: the random walk over a history of
            frames; ``noise_shared``: the share of its variance common to all clot nodes).
        wall_noise: scale (scaled coordinates) of the wall noise: clot nodes near the wall
            moved through it in every input frame, the targets by half as much
            (:func:`thrombojax.train.noise.add_wall_noise`; 0: off).
        history_noise: standard deviation (scaled coordinates) of the clot-wide shift of the
            frames before s_{t-1} (:func:`thrombojax.train.noise.add_history_noise`; 0: off).
        speed_noise: standard deviation of the factor ``1 + e`` the clot's input motion is
            scaled by (:func:`thrombojax.train.noise.add_speed_noise`; 0: off).
        speed_noise_steady: with ``speed_noise``, noise only the windows whose true clot keeps
            its speed within this fraction (``add_speed_noise``'s ``steady``; 0: every window).
        direction_noise: standard deviation per axis (radians) of the rotation the clot's
            input motion is turned by (:func:`thrombojax.train.noise.add_direction_noise`;
            0: off).
        swell_noise: standard deviation of the factor the clot's shape is scaled by about its
            centroid in the inputs, the targets taking half of it back
            (:func:`thrombojax.train.shape_noise.add_swell_noise`; 0: off).
        stretch_noise: the same along the clot's motion only
            (:func:`thrombojax.train.shape_noise.add_stretch_noise`; 0: off).
        time_scale: largest factor the window's clot motion is played faster or slower by
            (:func:`thrombojax.train.noise.time_scale_window`; 1: off).
        k: steps of the unrolled loss (1: the single-step loss).
        pushforward: steps applied first without gradients (push-forward training).
        flat_batch: run the model once on the batch as one flat graph
            (:mod:`thrombojax.simulator.flat`) where the model allows it
            (:func:`~thrombojax.simulator.flat.flat_batch_ok`); else, and by default,
            ``jax.vmap`` over the samples. Same loss and gradients (``tests/test_flat_batch.py``).
        clot_mean_weight: extra weight ``w`` of the clot-wide error: the loss adds ``w`` times
            the squared error of the clot's mean normalised acceleration
            (:mod:`thrombojax.train.loss`; 0: off, the plain per-node MSE).
        wall_loss_weight: weight ``w`` of the wall term: the loss adds ``w`` times the mean over
            the clot nodes of the squared excess of the predictions through the wall beyond the
            truth's (:mod:`thrombojax.train.wall_loss`; 0: off, no wall search compiled).
        speedup_weight, speedup_fraction: windows whose clean clot speeds up by more than
            ``speedup_fraction`` from its speed into s_t weigh ``1 + speedup_weight`` in every
            term of the loss (:func:`thrombojax.train.speedup.speedup_window_weight`; 0: off,
            nothing compiled). ``mse`` and ``nodes`` stay unweighted.
        push_guards: the rollout's coherence and containment applied to every push-forward
            step's prediction (:mod:`thrombojax.train.push_guards`; ``None``: off; needs
            ``pushforward >= 1``, not ``flat_batch``).
        input_guards: the same guards applied to the window's input frames after the noise
            (in training only; :func:`thrombojax.train.push_guards.guard_inputs`; ``None``:
            off; not ``flat_batch``).
        start_speed_noise: for a step with ``start_speed``, every window's start speed scaled
            by ``1 + e``, ``e ~ N(0, start_speed_noise^2)``, in training only
            (:func:`thrombojax.simulator.start_speed.jitter_start_speed`; 0: off).
    Returns:
        ``(loss, metrics)``: ``loss`` is the normalised-acceleration MSE (plus the weighted
        clot-wide and wall terms), a mean over the clot nodes weighted by their window's
        weight; ``metrics`` holds ``loss``, ``mse`` (the study's metric, scaled coordinates)
        and ``nodes``.
    """
    step = _as_step(model)
    size = batch.mask.shape[0]
    keys = jax.random.split(rng, size) if rng is not None else None

    corrupt = functools.partial(corrupt_window, current=step.history, noise_std=noise_std,
                                noise_gamma=noise_gamma, noise_walk=noise_walk,
                                noise_shared=noise_shared, wall_noise=wall_noise,
                                history_noise=history_noise, speed_noise=speed_noise,
                                speed_noise_steady=speed_noise_steady,
                                direction_noise=direction_noise, swell_noise=swell_noise,
                                stretch_noise=stretch_noise, time_scale=time_scale)

    wall_term = bool(wall_loss_weight)  # static: no wall search compiled when off
    lead = lead_count(step.rest_edges or push_guards is not None or input_guards is not None,
                      step.start_speed)  # lead frames: the rest frame, then the start frames
    if push_guards is not None and (flat_batch or not pushforward):
        raise ConfigError("push-forward guards need push-forward steps (--pushforward-steps "
                          ">= 1) and the vmapped batch (not flat_batch)")
    if input_guards is not None and flat_batch:
        raise ConfigError("input guards need the vmapped batch (not flat_batch)")

    def one(frames, node_type, mask, key):
        model_key, rest = None, None
        if lead:  # the window's lead frames, which no noise touches
            rest, frames = frames[0] if lead == 1 else frames[:lead], frames[lead:]
        if key is not None:
            noise_key, model_key = jax.random.split(key)
            if train:
                clean = frames
                frames = corrupt(noise_key, frames, node_type, mask)
                if input_guards is not None:
                    frames = guard_inputs(frames, clean, rest, node_type, mask, input_guards,
                                          step.history)
                if step.start_speed and start_speed_noise:
                    rest = jitter_start_speed(jax.random.fold_in(noise_key, 101), rest,
                                              start_speed_noise)
        return window_loss_terms(
            step, params, stats, frames, node_type, mask, k=k, pushforward=pushforward,
            train=train, rng=model_key, wall_term=wall_term, rest=rest, push_guards=push_guards,
        )

    if flat_batch and flat_batch_ok(step):
        terms = _flat_terms(step, params, stats, batch, keys, train=train, corrupt=corrupt,
                            k=k, pushforward=pushforward, wall_term=wall_term)
    elif keys is None:
        terms = jax.vmap(lambda f, t, m: one(f, t, m, None))(
            batch.frames, batch.node_type, batch.mask
        )
    else:
        terms = jax.vmap(one)(batch.frames, batch.node_type, batch.mask, keys)
    count = terms["count"].sum()
    denom = jnp.maximum(count, 1.0)
    total, loss_denom = jnp.sum, denom
    if speedup_weight:  # static: nothing compiled when off
        clean = batch.frames[:, lead:]
        weights = jax.vmap(functools.partial(
            speedup_window_weight, current=step.history, weight=speedup_weight,
            fraction=speedup_fraction))(clean, batch.node_type, batch.mask)
        loss_denom = jnp.maximum((weights * terms["count"]).sum(), 1.0)

        def total(x):
            return (weights * x).sum()

    loss = total(terms["loss_sum"]) / loss_denom
    if clot_mean_weight:
        loss = loss + clot_mean_weight * total(terms["clot_mean_sum"]) / loss_denom
    if wall_term:
        loss = loss + wall_loss_weight * total(terms["wall_sum"]) / loss_denom
    metrics = {"loss": loss, "mse": terms["mse_sum"].sum() / denom, "nodes": count}
    return loss, metrics


def _flat_terms(step, params, stats, batch, keys, *, train, corrupt, k, pushforward,
                wall_term=False):
    """The per-window loss terms with the model run once on the flat batch graph.

    Each sample's noise key is the one the vmapped form draws (the first half of its split key),
    so the noisy windows are the same; the model gets one key for the whole batch (the second
    half of the first sample's split: the flat step has one dropout stream).
    """
    frames, model_key = batch.frames, None
    if keys is not None:
        pairs = jax.vmap(jax.random.split)(keys)  # [B, 2] keys: (noise, model) per sample
        model_key = pairs[0, 1]
        if train:
            frames = jax.vmap(corrupt)(pairs[:, 0], frames, batch.node_type, batch.mask)
    return flat_window_loss_terms(FlatStep(step), params, stats, frames, batch.node_type,
                                  batch.mask, k=k, pushforward=pushforward, train=train,
                                  rng=model_key, wall_term=wall_term)


def make_train_step(
    model: Surrogate | LearnedStep,
    tx: optax.GradientTransformation,
    stats: TargetStats,
    *,
    noise_std: float = 0.0,
    noise_gamma: float = 0.1,
    noise_walk: bool = False,
    noise_shared: float = 0.0,
    wall_noise: float = 0.0,
    history_noise: float = 0.0,
    speed_noise: float = 0.0,
    speed_noise_steady: float = 0.0,
    direction_noise: float = 0.0,
    swell_noise: float = 0.0,
    stretch_noise: float = 0.0,
    time_scale: float = 1.0,
    k: int = 1,
    pushforward: int = 0,
    donate: bool = True,
    flat_batch: bool = False,
    clot_mean_weight: float = 0.0,
    wall_loss_weight: float = 0.0,
    speedup_weight: float = 0.0,
    speedup_fraction: float = 0.1,
    average_from: int | None = None,
    push_guards: PushGuards | None = None,
    input_guards: PushGuards | None = None,
    start_speed_noise: float = 0.0,
) -> Callable[[TrainState, Any, jax.Array], tuple[TrainState, dict]]:
    """Build the jitted ``train_step(state, batch, rng) -> (state, metrics)``.

    Args:
        model: the surrogate (static).
        tx: the optimiser.
        stats: target statistics (closed over, constants of the compiled step).
        noise_std, noise_gamma, noise_walk, noise_shared, wall_noise, history_noise,
            speed_noise, speed_noise_steady, direction_noise, swell_noise, stretch_noise,
            time_scale: training noise and time scaling (:func:`batch_loss`).
        k: steps of the unrolled loss (1: single step).
        pushforward: steps applied first without gradients (push-forward training).
        donate: donate the old state's buffers to the new one.
        flat_batch: the batch as one flat graph where the model allows it (:func:`batch_loss`).
        clot_mean_weight: extra weight of the clot-wide error in the loss (:func:`batch_loss`).
        wall_loss_weight: weight of the wall term in the loss (:func:`batch_loss`).
        speedup_weight, speedup_fraction: the extra loss weight of windows whose clot speeds
            up (:func:`batch_loss`).
        push_guards, input_guards: the guards of the push-forward steps and of the input
            frames (:func:`batch_loss`; ``None``: off).
        start_speed_noise: the noise on the start speed (:func:`batch_loss`; 0: off).
        average_from: with a state that carries an ``average`` (weight averaging), the number
            of steps done before the first averaged one: until then the average follows the
            weights, from then on it is their running mean (:func:`average_weights`).
    Returns:
        The jitted step. ``metrics`` adds ``grad_norm`` and ``lr``-independent scalars.
    """

    learned = _as_step(model)

    def step(state: TrainState, batch: Any, rng: jax.Array):
        def loss_fn(params):
            return batch_loss(
                learned, params, stats, batch, rng, train=True,
                noise_std=noise_std, noise_gamma=noise_gamma, noise_walk=noise_walk,
                noise_shared=noise_shared, wall_noise=wall_noise,
                history_noise=history_noise, speed_noise=speed_noise,
                speed_noise_steady=speed_noise_steady,
                direction_noise=direction_noise, swell_noise=swell_noise,
                stretch_noise=stretch_noise, time_scale=time_scale, k=k,
                pushforward=pushforward,
                flat_batch=flat_batch, clot_mean_weight=clot_mean_weight,
                wall_loss_weight=wall_loss_weight, speedup_weight=speedup_weight,
                speedup_fraction=speedup_fraction, push_guards=push_guards,
                input_guards=input_guards, start_speed_noise=start_speed_noise,
            )

        (_, metrics), grads = jax.value_and_grad(loss_fn, has_aux=True)(state.params)
        updates, opt_state = tx.update(grads, state.opt_state, state.params)
        params = optax.apply_updates(state.params, updates)
        metrics = dict(metrics, grad_norm=optax.tree.norm(grads))
        average = (None if state.average is None else
                   average_weights(state.average, params, state.step + 1, average_from or 0))
        new = TrainState(step=state.step + 1, params=params, opt_state=opt_state, average=average)
        return new, metrics

    return xla_jit(step, model=getattr(learned.model, "name", None), train=True,
                   donate_argnums=(0,) if donate else ())


def make_eval_step(
    model: Surrogate | LearnedStep, stats: TargetStats, *, k: int = 1
) -> Callable[[Any, Any], dict]:
    """Build the jitted ``eval_step(params, batch) -> metrics`` (no noise, no dropout).

    ``metrics`` holds the pooled ``loss`` and ``mse`` of the batch and its clot ``nodes``, so the
    caller averages over batches weighted by ``nodes``.
    """

    learned = _as_step(model)

    def step(params: Any, batch: Any):
        _, metrics = batch_loss(learned, params, stats, batch, None, train=False, k=k)
        return metrics

    return xla_jit(step, model=getattr(learned.model, "name", None))


def init_state(
    model: Surrogate | LearnedStep, tx: optax.GradientTransformation, rng: jax.Array, batch: Any,
    *, average: bool = False,
) -> TrainState:
    """Initialise the parameters on the first sample of ``batch`` and the optimiser state.

    Args:
        model: the surrogate (or its learned step). tx: the optimiser. rng: PRNG key.
        batch: a host :class:`thrombojax.data.batching.Batch` (its first sample is used).
        average: keep a running average of the weights (it starts as the weights).
    Returns:
        A :class:`TrainState` at step 0.
    """
    frames, step = batch.frames[0], _as_step(model)
    h, lead = step.history, lead_count(step.rest_edges, step.start_speed)  # frames[h]: after it
    rest, frames = (frames[:lead], frames[lead:]) if lead else (None, frames)
    params = step.init(rng, step.previous(frames, h, rest), frames[h], batch.node_type[0],
                       batch.mask[0])
    return TrainState(step=jnp.zeros((), jnp.int32), params=params, opt_state=tx.init(params),
                      average=jax.tree.map(jnp.copy, params) if average else None)
