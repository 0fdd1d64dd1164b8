"""Rollouts: the learned step applied in a loop, one ``jax.lax.scan`` compiled once.

- :func:`unroll`: ``n`` steps from ``(s_{t-1}, s_t)`` as a differentiable ``lax.scan``; the k-step
  training loss and the rollout are both this function.
- :func:`rollout`: the compiled rollout of a surrogate (:data:`rollout_jit`), optionally with
  physics guards after every step (:class:`~thrombojax.simulator.guard_set.GuardSet`), whose
  per-step corrections :func:`rollout_with_corrections` returns.
- :func:`constant_velocity_rollout`: the baseline every error is reported beside, the same rollout
  with the :class:`~thrombojax.models.registry.ConstantVelocity` surrogate (zero acceleration).

A learned step with a cell grid (:mod:`thrombojax.simulator.grid_step`) is rolled out with its
overflow flag accumulated over every step (:data:`rollout_jit` returns it); :func:`rollout` and
:func:`rollout_with_corrections` grow the grid and roll out again when it overflowed, or raise.
:func:`unroll` and :func:`guarded_unroll` do not return the flag, so they refuse such a step.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.errors import ConfigError
from thrombojax.models.registry import Surrogate, create_model, identity_stats
from thrombojax.simulator.grid_step import DEFAULT_MAX_REGROWS, run_checked
from thrombojax.simulator.guard_set import GuardSet
from thrombojax.simulator.step import LearnedStep, make_step
from thrombojax.types import TargetStats
from thrombojax.xla_options import jit as xla_jit
from thrombojax.xla_options import step_model_name

__all__ = [
    "unroll",
    "rollout_jit",
    "rollout",
    "rollout_with_corrections",
    "constant_velocity_rollout",
    "guarded_unroll",
    "as_step",
]


def as_step(model: Surrogate | LearnedStep) -> LearnedStep:
    """A :class:`LearnedStep` from a surrogate (or the step itself); checks it is hashable."""
    step = model if isinstance(model, LearnedStep) else make_step(model)
    try:
        hash(step)
    except TypeError as err:
        raise ConfigError(
            f"rollout: model {type(step.model).__name__} is not hashable; a Surrogate must be a "
            "frozen dataclass whose config holds tuples, not lists"
        ) from err
    return step


def unroll(
    step: LearnedStep,
    params: dict,
    stats: TargetStats,
    x_prev: jax.Array,
    x_cur: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    n_steps: int,
    *,
    train: bool = False,
    rng: jax.Array | None = None,
) -> tuple[jax.Array, jax.Array]:
    """Apply the learned step ``n_steps`` times, feeding each prediction back (``lax.scan``).

    Differentiable end to end (the k-step loss takes gradients through every step). Vessel and
    padded nodes stay at ``x_cur`` exactly (the step copies them).

    Args:
        step: the learned simulator. params, stats: its variables and statistics.
        x_prev, x_cur: ``[n_nodes, 3]`` scaled s_{t0-1}, s_{t0} (a step with ``history``
            H > 1: ``x_prev [H, n_nodes, 3]``, see :meth:`LearnedStep.previous`).
        node_type: ``[n_nodes]``. mask: ``[n_nodes]`` real nodes.
        n_steps: number of steps (static).
        train: training mode (dropout). rng: dropout key, folded with the step index.
    Returns:
        ``(positions [n_steps, n_nodes, 3], outputs [n_steps, n_nodes, 3])``: s_{t0+1} ...
        s_{t0+n_steps} and the raw model outputs of each step.
    """
    step.require_dense("unroll")
    positions, outputs, _, _ = _scan(step, params, stats, x_prev, x_cur, node_type, mask,
                                     n_steps, train=train, rng=rng)
    return positions, outputs


def _scan(step, params, stats, x_prev, x_cur, node_type, mask, n_steps, *, train=False,
          rng=None, guards: GuardSet | None = None):
    """The scan behind :func:`unroll` and the rollout: ``(positions, outputs, corrections,
    overflow)``, ``overflow`` True if the graph of any step overflowed."""

    # the rigid vessel's search, made once; the barrier keeps XLA from sinking it into the
    # loop (where it ran at every step again: measured 80 against 48 ms per step)
    context = jax.lax.optimization_barrier(step.context(x_cur, node_type, mask))

    def body(carry, i):
        prev, cur, overflow = carry
        key = None if rng is None else jax.random.fold_in(rng, i)
        out = step(params, stats, prev, cur, node_type, mask, train=train, rng=key,
                   context=context)
        new_prev, nxt, corrections = ((step.shift(prev, cur), out.positions, {}) if guards is None
                                      else guards.advance(step.shift, prev, cur, out.positions))
        return (new_prev, nxt, overflow | out.overflow), (nxt, out.output, corrections)

    (_, _, overflow), (positions, outputs, corrections) = jax.lax.scan(
        body, (x_prev, x_cur, jnp.zeros((), bool)), jnp.arange(n_steps))
    return positions, outputs, corrections, overflow


def guarded_unroll(step, params, stats, x0_prev, x0, node_type, mask, n_steps, context):
    """A member rollout with guards for :func:`thrombojax.simulator.ensemble.ensemble_rollout`
    (its ``rollout_fn``; ``context`` is the :class:`GuardSet`): ``(positions, corrections)``."""
    step.require_dense("an ensemble rollout")
    positions, _, corrections, _ = _scan(step, params, stats, x0_prev, x0, node_type, mask,
                                         n_steps, guards=context)
    return positions, corrections


def _rollout_impl(step, params, stats, x0_prev, x0, node_type, mask, n_steps, guards=None):
    positions, _, corrections, overflow = _scan(step, params, stats, x0_prev, x0, node_type, mask,
                                                n_steps, guards=guards)
    return positions, corrections, overflow


rollout_jit = xla_jit(_rollout_impl, model_of=step_model_name,
                      static_argnames=("step", "n_steps"))
"""The compiled rollout ``(step, params, stats, x0_prev, x0, node_type, mask, n_steps, guards)
-> (trajectory [n_steps, n_nodes, 3], corrections {guard: [n_steps, n_nodes]}, overflow [])``;
``guards`` is a :class:`~thrombojax.simulator.guard_set.GuardSet` or ``None`` (then
``corrections`` is empty); ``overflow`` is True if the cell grid of any step overflowed (the
trajectory is then unreliable: :func:`rollout_with_corrections` re-allocates). One
compilation per (step, shapes, n_steps, guard switches); ``rollout_jit._cache_size()`` counts
them."""


def rollout(
    model: Surrogate | LearnedStep,
    params: dict,
    stats: TargetStats,
    x0_prev: jax.Array,
    x0: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    n_steps: int,
    *,
    guards: GuardSet | None = None,
    max_regrows: int = DEFAULT_MAX_REGROWS,
) -> jax.Array:
    """Autoregressive rollout as one compiled ``jax.lax.scan`` over the learned step.

    Compiled once per (model, node count, ``n_steps``): a second call with new positions
    or parameters of the same shapes reuses the compiled program. Works on any fixed node
    set: the full resolution cloud or a subset kept for the whole rollout
    (:func:`thrombojax.data.augment.select_subset`).

    Args:
        model: a surrogate or its :class:`LearnedStep`.
        params, stats: its parameters and target statistics.
        x0_prev: ``[n_nodes, 3]`` scaled positions s_{t0-1} (a step with ``history`` H > 1:
            ``[H, n_nodes, 3]``, :meth:`LearnedStep.previous`).
        x0: ``[n_nodes, 3]`` scaled positions s_{t0}.
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
        n_steps: number of predicted frames (static).
        guards: physics guards applied after every step (``None``: the model alone).
        max_regrows: a step with a cell grid: re-allocations of the grid allowed when it
            overflowed (each grows it: :func:`thrombojax.graph.grow`) before
            :class:`~thrombojax.errors.CapacityOverflowError` is raised.
    Returns:
        ``[n_steps, n_nodes, 3]`` predicted s_{t0+1} ... s_{t0+n_steps} (device array); vessel and
        padded nodes equal ``x0`` exactly.
    """
    return rollout_with_corrections(model, params, stats, x0_prev, x0, node_type, mask, n_steps,
                                    guards=guards, max_regrows=max_regrows)[0]


def rollout_with_corrections(
    model: Surrogate | LearnedStep,
    params: dict,
    stats: TargetStats,
    x0_prev: jax.Array,
    x0: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    n_steps: int,
    *,
    guards: GuardSet | None = None,
    max_regrows: int = DEFAULT_MAX_REGROWS,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """:func:`rollout` that also returns how far each guard moved every node at every step.

    A step with a cell grid is rolled out again on a grown grid whenever any step overflowed
    (:func:`thrombojax.simulator.grid_step.run_checked`); without one the flag is never read.

    Returns:
        ``(trajectory [n_steps, n_nodes, 3], {guard name: correction [n_steps, n_nodes]})``
        (distances in the rollout's coordinates; empty without guards).
    """
    step = as_step(model)
    if int(n_steps) < 1:
        raise ConfigError(f"rollout: n_steps must be >= 1, got {n_steps}")
    step.check_previous(x0_prev, np.shape(x0)[0], "rollout")
    args = (params, stats, jnp.asarray(x0_prev, jnp.float32), jnp.asarray(x0, jnp.float32),
            jnp.asarray(node_type, jnp.int32), jnp.asarray(mask, bool))

    def run(s: LearnedStep):
        traj, corrections, overflow = rollout_jit(s, *args, int(n_steps), guards)
        return (traj, corrections), overflow

    return run_checked(run, step, max_regrows=max_regrows, what="rollout")[0]


def constant_velocity_rollout(
    x0_prev: np.ndarray, x0: np.ndarray, node_type: np.ndarray, mask: np.ndarray, n_steps: int
) -> np.ndarray:
    """The constant-velocity baseline ``s_{t0+k} = s_{t0} + k (s_{t0} - s_{t0-1})`` (clot nodes).

    The rollout of the :class:`~thrombojax.models.registry.ConstantVelocity` surrogate with
    identity statistics (zero physical acceleration), so the baseline runs the same code as
    every model.

    Returns:
        ``[n_steps, n_nodes, 3]`` float32 numpy; vessel and padded nodes stay at ``x0``.
    """
    cv = create_model("constant_velocity")
    return np.asarray(rollout(cv, {}, identity_stats(), x0_prev, x0, node_type, mask, n_steps))
