"""Ensembles of rollouts in one compiled program: M models, or M perturbed starts of one model.

Both variants are one ``jax.jit`` of ``jax.vmap`` over the members of the ``lax.scan`` rollout
(:func:`thrombojax.simulator.rollout.unroll`), compiled once per (learned step, member count,
node count, ``n_steps``)::

    params_stack = stack_params([p0, p1, p2])                # leaves [M, ...]
    ens = ensemble_rollout(model, params_stack, stats, x0_prev, x0, node_type, mask, n_steps)
    ens.mean        # [n_steps, N, 3]   member mean of the positions
    ens.spread      # [n_steps, N]      per-node standard deviation of the position
    ens.members     # [M, n_steps, N, 3]

    ens = stochastic_rollout(model, params, stats, x0_prev, x0, node_type, mask, n_steps,
                             n_members=8, noise_std=1e-3, rng=jax.random.key(0))

**Spread** is ``sqrt(trace(C) / 3)``, ``C`` the 3x3 population covariance (divisor M, not M - 1)
of a node's position over the members: the root-mean-square over the three axes of the
per-axis standard deviation, in the rollout's (scaled) length unit. It is computed from the
deviations from member 0 (shifted data), so M identical members give a mean equal to member 0
bit for bit and a spread of exactly 0, and nodes that no member moves (vessel, padding) have
spread exactly 0.

The stochastic variant perturbs s_{t0} of the real clot nodes of each member with Gaussian noise
of standard deviation ``noise_std`` (scaled units) and keeps s_{t0-1}, as the training noise does
(:mod:`thrombojax.train.noise`): the perturbation enters both the position and the velocity.

A custom member rollout (e.g. one with physics guards) plugs in through ``rollout_fn``, a
hashable callable ``rollout_fn(step, params, stats, x0_prev, x0, node_type, mask, n_steps,
context)`` returning positions ``[n_steps, N, 3]`` or ``(positions, aux)``; ``context`` is any
pytree shared by all members (a wall), ``aux`` any pytree, returned stacked per member.
With the guards as member rollout (:func:`thrombojax.simulator.rollout.guarded_unroll`, the
:class:`~thrombojax.simulator.guard_set.GuardSet` as ``context``) pass ``guard_mean=True``:
every member stays in the vessel, but their mean need not (the mean of two clots on either
side of a bend cuts the corner: measured, 62 % of a two-member ClotEntry mean outside the
vessel), so the same guards are applied to the mean of every step too, and how far they moved
it is returned in ``mean_corrections``. The mean is an output only: members never see it.
``member_batch`` runs the members in chunks (a ``lax.map`` of vmapped chunks, one program) when
all M at once do not fit in memory.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from thrombojax.errors import ConfigError
from thrombojax.models.registry import Surrogate
from thrombojax.simulator.guard_set import GuardSet
from thrombojax.simulator.rollout import as_step, unroll
from thrombojax.simulator.step import LearnedStep
from thrombojax.types import TargetStats, clot_mask
from thrombojax.xla_options import jit as xla_jit
from thrombojax.xla_options import step_model_name

__all__ = [
    "EnsembleRollout",
    "stack_params",
    "n_members",
    "ensemble_stats",
    "ensemble_rollout",
    "stochastic_rollout",
    "ensemble_jit",
    "plain_unroll",
    "check_rollout_start",
]


@struct.dataclass
class EnsembleRollout:
    """The rollouts of M members and their summary (device arrays).

    Attributes:
        mean: ``[n_steps, N, 3]`` member mean of the predicted positions s_{t0+1} ...
        spread: ``[n_steps, N]`` per-node std of the position, ``sqrt(trace(cov) / 3)``
            (population covariance over members); 0 on vessel and padded nodes.
        members: ``[M, n_steps, N, 3]`` every member's rollout.
        aux: what a custom ``rollout_fn`` returned besides positions, stacked ``[M, ...]``
            (``None`` for the plain rollout).
        mean_corrections: with ``guard_mean``, how far each guard moved every node of the
            mean, ``{guard name: [n_steps, N]}`` (``None`` without).
    """

    mean: jax.Array
    spread: jax.Array
    members: jax.Array
    aux: Any = None
    mean_corrections: Any = None

    @property
    def n_members(self) -> int:
        """M."""
        return int(self.members.shape[0])


def stack_params(params_list: Sequence[Any]) -> Any:
    """Stack M parameter trees of the same structure and shapes into one tree of ``[M, ...]``.

    Args:
        params_list: M >= 1 parameter pytrees (e.g. ``TrainedModel.params`` of each member).
    Returns:
        One pytree whose leaves are ``[M, *leaf.shape]`` arrays.
    Raises:
        ConfigError: empty list, or a member whose tree structure, leaf shapes or dtypes differ
            from member 0's (the message names the member and the first differing leaf).
    """
    params_list = list(params_list)
    if not params_list:
        raise ConfigError("stack_params: no members to stack")
    ref_struct = jax.tree.structure(params_list[0])
    ref = _leaf_shapes(params_list[0])
    for i, params in enumerate(params_list[1:], start=1):
        if jax.tree.structure(params) != ref_struct:
            missing = sorted(set(ref) ^ set(_leaf_shapes(params)))
            raise ConfigError(f"stack_params: member {i} has another parameter tree than member "
                              f"0 (differs at {missing[:3] or 'the tree structure'})")
        got = _leaf_shapes(params)
        for key, want in ref.items():
            if got[key] != want:
                raise ConfigError(f"stack_params: member {i} leaf {key} is {got[key]}, member 0's "
                                  f"is {want} (shape, dtype)")
    return jax.tree.map(lambda *a: jnp.stack([jnp.asarray(x) for x in a]), *params_list)


def _leaf_shapes(tree: Any) -> dict[str, tuple]:
    flat = jax.tree_util.tree_flatten_with_path(tree)[0]
    return {jax.tree_util.keystr(k): (tuple(jnp.shape(v)), str(jnp.result_type(v)))
            for k, v in flat}


def n_members(params_stack: Any) -> int:
    """M, the leading axis of every leaf of a stacked parameter tree (ConfigError if they differ
    or the tree has no leaves)."""
    sizes = {int(jnp.shape(x)[0]) if jnp.ndim(x) else -1 for x in jax.tree.leaves(params_stack)}
    if len(sizes) != 1 or -1 in sizes:
        raise ConfigError(f"params_stack: leaves must share a leading member axis, got sizes "
                          f"{sorted(sizes) or 'none (no leaves)'}; build it with stack_params")
    return sizes.pop()


def ensemble_stats(members: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Member mean and per-node spread of stacked rollouts (jittable; see the module docstring).

    Args:
        members: ``[M, ..., 3]`` positions of M members (e.g. ``[M, n_steps, N, 3]``).
    Returns:
        ``(mean [..., 3], spread [...])``: spread ``= sqrt(trace(cov) / 3)`` with the population
        covariance over members; M identical members give ``mean == members[0]`` exactly and
        spread exactly 0.
    """
    dev = members - members[0]  # shifted data: exact zeros where members agree
    dmean = dev.mean(axis=0)
    mean = members[0] + dmean
    var = jnp.mean(jnp.square(dev - dmean), axis=0)  # [..., 3] per-axis population variance
    return mean, jnp.sqrt(var.mean(axis=-1))


def plain_unroll(step, params, stats, x0_prev, x0, node_type, mask, n_steps, context):
    """The default member rollout: :func:`thrombojax.simulator.rollout.unroll`'s positions
    ``[n_steps, N, 3]`` (``context`` is ignored)."""
    del context
    return unroll(step, params, stats, x0_prev, x0, node_type, mask, n_steps)[0]


def _ensemble_impl(step, params, stats, x0_prev, x0, node_type, mask, context, n_steps,
                   params_batched, state_batched, rollout_fn, member_batch=None,
                   guard_mean=False):
    def member(p, xp, xc):
        out = rollout_fn(step, p, stats, xp, xc, node_type, mask, n_steps, context)
        return out if isinstance(out, tuple) else (out, None)

    if member_batch is None:  # all members side by side
        axis_p = 0 if params_batched else None
        axis_s = 0 if state_batched else None
        members, aux = jax.vmap(member, in_axes=(axis_p, axis_s, axis_s))(params, x0_prev, x0)
    else:  # a loop over chunks of member_batch vmapped members (less memory)
        mapped = (params if params_batched else None, (x0_prev, x0) if state_batched else None)

        def chunk(xs):
            p = xs[0] if params_batched else params
            xp, xc = xs[1] if state_batched else (x0_prev, x0)
            return member(p, xp, xc)

        members, aux = jax.lax.map(chunk, mapped, batch_size=member_batch)
    mean, spread = ensemble_stats(members)
    spread = jnp.where(clot_mask(node_type, mask)[None], spread, 0.0)
    mean_corrections = None
    if guard_mean:  # the guards on the mean of every step (an output; members never see it)
        mean, mean_corrections = jax.vmap(context.apply)(mean)
    return EnsembleRollout(mean=mean, spread=spread, members=members, aux=aux,
                           mean_corrections=mean_corrections)


ensemble_jit = xla_jit(
    _ensemble_impl, model_of=step_model_name,
    static_argnames=("step", "n_steps", "params_batched", "state_batched", "rollout_fn",
                     "member_batch", "guard_mean"),
)
"""The compiled ensemble ``(step, params, stats, x0_prev, x0, node_type, mask, context, n_steps,
params_batched, state_batched, rollout_fn, member_batch=None, guard_mean=False) ->
EnsembleRollout``: the member
rollouts are vmapped over the leading axis of ``params`` (``params_batched``) and / or of
``x0_prev``, ``x0`` (``state_batched``), all at once or (``member_batch``) in a ``lax.map`` over
chunks of that many members; ``guard_mean`` applies ``context`` (a ``GuardSet``) to the mean.
One compilation per (step, M, N, ``n_steps``, flags, ``rollout_fn``, ``member_batch``);
``ensemble_jit._cache_size()`` counts them."""


def check_rollout_start(step: LearnedStep, n_steps: int, x0_prev, x0, node_type, mask, *,
                        what: str = "ensemble rollout") -> tuple:
    """The start of a multi-member rollout checked and cast: ``(x0_prev, x0, node_type, mask)``
    as float32 / int32 / bool arrays; ConfigError (naming ``what``) for ``n_steps < 1`` or
    arrays that do not fit the node count."""
    if int(n_steps) < 1:
        raise ConfigError(f"{what}: n_steps must be >= 1, got {n_steps}")
    x0_prev, x0 = jnp.asarray(x0_prev, jnp.float32), jnp.asarray(x0, jnp.float32)
    node_type, mask = jnp.asarray(node_type, jnp.int32), jnp.asarray(mask, bool)
    n = node_type.shape[0]
    if x0.shape != (n, 3) or mask.shape != (n,):
        raise ConfigError(f"{what}: x0 {x0.shape}, mask {mask.shape} do not fit {n} "
                          f"nodes ([N, 3], [N])")
    step.check_previous(x0_prev, n, what)
    return x0_prev, x0, node_type, mask


def _member_batch(member_batch: int | None, m: int) -> int | None:
    """``None`` (all members vmapped) or a chunk size in [1, M)."""
    if member_batch is None or int(member_batch) >= m:
        return None
    if int(member_batch) < 1:
        raise ConfigError(f"ensemble rollout: member_batch must be >= 1, got {member_batch}")
    return int(member_batch)


def _guard_mean(guard_mean: bool, context: Any) -> bool:
    """``guard_mean`` checked: it needs the guards (a :class:`GuardSet`) as ``context``."""
    if guard_mean and not isinstance(context, GuardSet):
        raise ConfigError(f"ensemble rollout: guard_mean needs the members' GuardSet as context, "
                          f"got {type(context).__name__}")
    return bool(guard_mean)


def _perturb(rng, x0, node_type, mask, n: int, noise_std: float) -> jax.Array:
    """``[n, N, 3]``: x0 plus Gaussian noise of std ``noise_std`` on real clot nodes."""
    if rng is None:
        raise ConfigError("ensemble rollout: noise_std > 0 needs an rng key")
    noise = noise_std * jax.random.normal(rng, (n, *x0.shape), jnp.float32)
    return jnp.where(clot_mask(node_type, mask)[None, :, None], x0[None] + noise, x0[None])


def ensemble_rollout(
    model: Surrogate | LearnedStep,
    params_stack: Any,
    stats: TargetStats,
    x0_prev: jax.Array,
    x0: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    n_steps: int,
    *,
    noise_std: float = 0.0,
    rng: jax.Array | None = None,
    rollout_fn: Callable | None = None,
    context: Any = None,
    member_batch: int | None = None,
    guard_mean: bool = False,
) -> EnsembleRollout:
    """Roll out M models (stacked parameters) from the same start, in one compiled program.

    Args:
        model: the surrogate (or its :class:`LearnedStep`) shared by all members.
        params_stack: parameters with a leading member axis ``[M, ...]`` (:func:`stack_params`).
        stats: target statistics shared by all members (an ensemble trained on one split).
        x0_prev, x0: ``[N, 3]`` scaled s_{t0-1}, s_{t0} (``x0_prev [H, N, 3]`` for a step with
            a history of H frames).
        node_type: ``[N]`` NodeType values. mask: ``[N]`` real-node mask.
        n_steps: number of predicted frames (static).
        noise_std: also perturb each member's s_{t0} (clot nodes) by this Gaussian std, in
            scaled units (0: every member starts from the same state).
        rng: PRNG key of the perturbations (needed when ``noise_std > 0``).
        rollout_fn, context: a custom member rollout and its shared pytree (module docstring);
            ``None``: :func:`plain_unroll`.
        member_batch: run the members in chunks of this many (a ``lax.map`` of vmapped
            chunks, still one program; bounds memory on large clouds); ``None``: all at once.
        guard_mean: also apply ``context`` (the members' :class:`GuardSet`) to the mean of
            every step; how far it moved is ``mean_corrections`` (module docstring).
    Returns:
        The :class:`EnsembleRollout` (``members [M, n_steps, N, 3]``).
    """
    step = as_step(model)
    x0_prev, x0, node_type, mask = check_rollout_start(step, n_steps, x0_prev, x0, node_type,
                                                       mask)
    m = n_members(params_stack)
    noisy = float(noise_std) > 0.0
    if noisy:
        x0 = _perturb(rng, x0, node_type, mask, m, float(noise_std))
        x0_prev = jnp.broadcast_to(x0_prev, (m, *x0_prev.shape))
    return ensemble_jit(step, params_stack, stats, x0_prev, x0, node_type, mask, context,
                        int(n_steps), params_batched=True, state_batched=noisy,
                        rollout_fn=rollout_fn or plain_unroll,
                        member_batch=_member_batch(member_batch, m),
                        guard_mean=_guard_mean(guard_mean, context))


def stochastic_rollout(
    model: Surrogate | LearnedStep,
    params: Any,
    stats: TargetStats,
    x0_prev: jax.Array,
    x0: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    n_steps: int,
    *,
    n_members: int,
    noise_std: float,
    rng: jax.Array,
    rollout_fn: Callable | None = None,
    context: Any = None,
    member_batch: int | None = None,
    guard_mean: bool = False,
) -> EnsembleRollout:
    """Roll out one model from M perturbed starts, in one compiled program.

    Member i starts from ``(x0_prev, x0 + n_i)``, ``n_i`` Gaussian of std ``noise_std`` (scaled
    units) on real clot nodes, zero elsewhere (module docstring).

    Args:
        model, params, stats: the surrogate (or its learned step), its parameters, statistics.
        x0_prev, x0: ``[N, 3]`` scaled s_{t0-1}, s_{t0} (``x0_prev [H, N, 3]`` for a step with
            a history of H frames).
        node_type: ``[N]``. mask: ``[N]`` real nodes. n_steps: predicted frames (static).
        n_members: M >= 1. noise_std: perturbation std, > 0 (scaled units). rng: PRNG key.
        rollout_fn, context, member_batch, guard_mean: as in :func:`ensemble_rollout`.
    Returns:
        The :class:`EnsembleRollout` (``members [M, n_steps, N, 3]``).
    """
    step = as_step(model)
    x0_prev, x0, node_type, mask = check_rollout_start(step, n_steps, x0_prev, x0, node_type,
                                                       mask)
    if int(n_members) < 1 or not float(noise_std) > 0.0:
        raise ConfigError(f"stochastic rollout: needs n_members >= 1 and noise_std > 0, got "
                          f"{n_members} and {noise_std}")
    starts = _perturb(rng, x0, node_type, mask, int(n_members), float(noise_std))
    prevs = jnp.broadcast_to(x0_prev, (starts.shape[0], *x0_prev.shape))
    return ensemble_jit(step, params, stats, prevs, starts, node_type, mask, context,
                        int(n_steps), params_batched=False, state_batched=True,
                        rollout_fn=rollout_fn or plain_unroll,
                        member_batch=_member_batch(member_batch, int(n_members)),
                        guard_mean=_guard_mean(guard_mean, context))
