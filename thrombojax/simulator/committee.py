"""Committee rollouts: M models that take every step together, one compiled ``lax.scan``.

:func:`thrombojax.simulator.ensemble.ensemble_rollout` rolls M members out independently and
averages their trajectories afterwards. Over a long rollout the members drift apart, and the
mean of clots far apart along a bent vessel is no clot: it cuts the corner (``guard_mean``
puts it back inside). A committee rollout averages the M members' predicted next frames at
every step instead, applies the guards to that mean, and feeds the mean back to every member::

    p_i   = step_i(s_{t-1}, s_t)                 # each member's next frame, same state
    s_t+1 = guards(mean_i p_i)                   # one state, inside the vessel
    spread_t+1 = sqrt(trace(cov_i p_i) / 3)      # the members' disagreement on this one step

One trajectory, as cheap per step as the ensemble (M forward passes, vmapped). Its spread is
the disagreement of one step from a shared state, not an error accumulated over the rollout,
so it is smaller than the independent ensemble's and measures something else.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from thrombojax.errors import ConfigError
from thrombojax.models.registry import Surrogate
from thrombojax.simulator.ensemble import (
    EnsembleRollout,
    check_rollout_start,
    ensemble_stats,
    n_members,
)
from thrombojax.simulator.guard_set import GuardSet
from thrombojax.simulator.rollout import as_step
from thrombojax.simulator.step import LearnedStep
from thrombojax.types import TargetStats, clot_mask
from thrombojax.xla_options import jit as xla_jit
from thrombojax.xla_options import step_model_name

__all__ = ["committee_rollout", "committee_jit"]


def _committee_impl(step, params, stats, x0_prev, x0, node_type, mask, guards, n_steps):
    clot = clot_mask(node_type, mask)
    # the rigid vessel's search, made once (the barrier: see thrombojax.simulator.rollout)
    context = jax.lax.optimization_barrier(step.context(x0, node_type, mask))

    def body(carry, _):
        prev, cur = carry
        preds = jax.vmap(lambda p: step(p, stats, prev, cur, node_type, mask,
                                        context=context).positions)(params)
        mean, spread = ensemble_stats(preds)
        new_prev, nxt, corrections = ((step.shift(prev, cur), mean, {}) if guards is None
                                      else guards.advance(step.shift, prev, cur, mean))
        return (new_prev, nxt), (preds, nxt, jnp.where(clot, spread, 0.0), corrections)

    _, (preds, positions, spread, corrections) = jax.lax.scan(
        body, (x0_prev, x0), None, length=n_steps)
    return EnsembleRollout(mean=positions, spread=spread, members=jnp.swapaxes(preds, 0, 1),
                           mean_corrections=corrections if guards is not None else None)


committee_jit = xla_jit(_committee_impl, model_of=step_model_name,
                        static_argnames=("step", "n_steps"))
"""The compiled committee rollout ``(step, params_stack, stats, x0_prev, x0, node_type, mask,
guards, n_steps) -> EnsembleRollout``; one compilation per (step, M, N, ``n_steps``, guard
switches)."""


def committee_rollout(
    model: Surrogate | LearnedStep,
    params_stack: Any,
    stats: TargetStats,
    x0_prev: jax.Array,
    x0: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    n_steps: int,
    *,
    guards: GuardSet | None = None,
) -> EnsembleRollout:
    """Roll M models out as a committee: their mean next frame, guarded, fed back every step.

    Args:
        model: the surrogate (or its :class:`LearnedStep`) shared by all members; a step with a
            cell grid is refused (its overflow flag is not carried here).
        params_stack: parameters with a leading member axis ``[M, ...]``
            (:func:`thrombojax.simulator.ensemble.stack_params`).
        stats: target statistics shared by all members.
        x0_prev, x0: ``[N, 3]`` scaled s_{t0-1}, s_{t0} (``x0_prev [H, N, 3]`` for a step with
            a history of H frames).
        node_type: ``[N]`` NodeType values. mask: ``[N]`` real-node mask.
        n_steps: number of predicted frames (static).
        guards: physics guards applied to the mean of every step before it is fed back
            (``None``: the committee alone).
    Returns:
        An :class:`~thrombojax.simulator.ensemble.EnsembleRollout`: ``mean [n_steps, N, 3]`` the
        committee's trajectory; ``spread [n_steps, N]`` the members' one-step disagreement
        (0 off the clot); ``members [M, n_steps, N, 3]`` each member's prediction of every step
        from the committee's state; ``mean_corrections`` how far each guard moved the mean
        (``None`` without guards).
    """
    step = as_step(model)
    step.require_dense("a committee rollout")
    x0_prev, x0, node_type, mask = check_rollout_start(
        step, n_steps, x0_prev, x0, node_type, mask, what="committee rollout")
    n_members(params_stack)  # a stacked tree, or a clear error
    if guards is not None and not isinstance(guards, GuardSet):
        raise ConfigError(f"committee rollout: guards must be a GuardSet or None, got "
                          f"{type(guards).__name__}")
    return committee_jit(step, params_stack, stats, x0_prev, x0, node_type, mask, guards,
                         int(n_steps))
