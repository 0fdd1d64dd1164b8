"""One pure prediction step and its ``jax.lax.scan`` rollout.

The step is shared by training (teacher-forced single steps) and rollouts:

    inputs  = (s_t, v_t = s_t - s_{t-1}, node type, mask)       # scaled [-1, 1] coordinates
    out     = model(inputs, graph built from s_t)                  # normalised acceleration
    a_t     = out * std + mean                                     # TargetStats, training split
    s_{t+1} = s_t + v_t + a_t  for clot nodes;  s_t for vessel and padded nodes (rigid, copied)
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.errors import CapacityOverflowError, ConfigError
from thrombojax.types import ModelInput, NodeType, TargetStats

__all__ = [
    "make_input",
    "target_acceleration",
    "integrate",
    "predict_next",
    "rollout_step",
    "rollout_jit",
    "rollout_with_overflow",
    "rollout",
    "constant_velocity_rollout",
    "select_subset",
]


def make_input(
    x_prev: jax.Array,
    x_cur: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    velocity_scale: jax.Array | float = 1.0,
) -> ModelInput:
    """Build the model input of one frame.

    Args:
        x_prev: ``[n_nodes, 3]`` positions s_{t-1} (scaled).
        x_cur: ``[n_nodes, 3]`` positions s_t (scaled).
        node_type: ``[n_nodes]`` int NodeType values.
        mask: ``[n_nodes]`` bool, True for real nodes.
        velocity_scale: the velocity feature is ``(s_t - s_{t-1}) / velocity_scale``
            (``TargetStats.velocity_std``).
    Returns:
        The :class:`ModelInput` with the (normalised) velocity, zero on padded nodes.
    """
    velocity = jnp.where(mask[:, None], (x_cur - x_prev) / velocity_scale, 0.0)
    return ModelInput(
        positions=x_cur,
        velocity=velocity,
        node_type=node_type.astype(jnp.int32),
        mask=mask,
    )


def target_acceleration(x_prev: jax.Array, x_cur: jax.Array, x_next: jax.Array) -> jax.Array:
    """The update the models learn: ``a_t = s_{t+1} - 2 s_t + s_{t-1}``, ``[n_nodes, 3]``."""
    return x_next - 2.0 * x_cur + x_prev


def integrate(
    x_prev: jax.Array,
    x_cur: jax.Array,
    accel: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
) -> jax.Array:
    """Second-order update ``s_{t+1} = s_t + (s_t - s_{t-1}) + a_t`` for real clot nodes.

    Vessel nodes and padded nodes are copied from ``x_cur`` exactly (the vessel is rigid).

    Returns:
        ``[n_nodes, 3]`` positions s_{t+1}.
    """
    moving = mask & (node_type == NodeType.CLOT)
    return jnp.where(moving[:, None], x_cur + (x_cur - x_prev) + accel, x_cur)


def predict_next(
    model: Any,
    params: Any,
    stats: TargetStats,
    x_prev: jax.Array,
    x_cur: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    train: bool = False,
    rng: jax.Array | None = None,
) -> tuple[jax.Array, jax.Array]:
    """One surrogate step: build graph from s_t, run the model, integrate.

    Args:
        model: a surrogate from :func:`thrombojax.models.create_model`.
        params: its parameters.
        stats: normalisation statistics of the acceleration.
        x_prev, x_cur: ``[n_nodes, 3]`` scaled positions s_{t-1}, s_t.
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
    Returns:
        ``(x_next [n_nodes, 3], out [n_nodes, 3])``: the next positions and the raw
        (normalised) model output.
    """
    inputs = make_input(x_prev, x_cur, node_type, mask, stats.velocity_std)
    graph = model.build_graph(inputs)
    out = model.apply(params, inputs, graph, train=train, rng=rng)
    accel = stats.denormalize(out)
    return integrate(x_prev, x_cur, accel, node_type, mask), out


# ---- the rollout: one pure step under jax.lax.scan ----------------------------------------


def _graph_overflow(graph: Any) -> jax.Array:
    """The graph's overflow flag as a bool scalar (False if the graph has none)."""
    flag = graph.get("overflow") if isinstance(graph, dict) else getattr(graph, "overflow", None)
    if flag is None:
        return jnp.zeros((), bool)
    return jnp.any(jnp.asarray(flag))


def rollout_step(
    model: Any,
    params: Any,
    stats: TargetStats,
    x_fixed: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    carry: tuple[jax.Array, jax.Array],
) -> tuple[tuple[jax.Array, jax.Array], tuple[jax.Array, jax.Array]]:
    """One pure rollout step, the body of the scan.

    Rebuild the graph from s_t -> model -> integrate -> hold vessel and padded nodes
    exactly at ``x_fixed`` (their initial positions; the vessel is rigid).

    Args:
        model, params, stats: as in :func:`predict_next`.
        x_fixed: ``[n_nodes, 3]`` positions the non-moving nodes are held at.
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
        carry: ``(s_{t-1}, s_t)``, each ``[n_nodes, 3]``.
    Returns:
        ``((s_t, s_{t+1}), (s_{t+1} [n_nodes, 3], overflow bool[]))``.
    """
    x_prev, x_cur = carry
    inputs = make_input(x_prev, x_cur, node_type, mask, stats.velocity_std)
    graph = model.build_graph(inputs)
    out = model.apply(params, inputs, graph, train=False, rng=None)
    x_next = integrate(x_prev, x_cur, stats.denormalize(out), node_type, mask)
    moving = mask & (node_type == NodeType.CLOT)
    x_next = jnp.where(moving[:, None], x_next, x_fixed)
    return (x_cur, x_next), (x_next, _graph_overflow(graph))


def _rollout_impl(model, params, stats, x0_prev, x0, node_type, mask, n_steps):
    def body(carry, _):
        return rollout_step(model, params, stats, x0, node_type, mask, carry)

    _, (traj, overflow) = jax.lax.scan(body, (x0_prev, x0), None, length=n_steps)
    return traj, overflow


rollout_jit = jax.jit(_rollout_impl, static_argnames=("model", "n_steps"))
"""The compiled rollout ``(model, params, stats, x0_prev, x0, node_type, mask, n_steps) ->
(trajectory [n_steps, n_nodes, 3], overflow [n_steps] bool)``; one compilation per
(model, shapes, n_steps). ``rollout_jit._cache_size()`` counts the compilations."""


def rollout_with_overflow(
    model: Any,
    params: Any,
    stats: TargetStats,
    x0_prev: jax.Array,
    x0: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    n_steps: int,
) -> tuple[jax.Array, jax.Array]:
    """Roll a surrogate out for ``n_steps`` steps; also return the per-step overflow flags.

    Same arguments as :func:`rollout`. Returns ``(trajectory [n_steps, n_nodes, 3],
    overflow [n_steps] bool)`` (device arrays, not synchronised).
    """
    try:
        hash(model)
    except TypeError as err:
        raise ConfigError(
            f"rollout: model {type(model).__name__} is not hashable; a Surrogate must be a frozen "
            "dataclass whose config holds tuples, not lists"
        ) from err
    if int(n_steps) < 1:
        raise ConfigError(f"rollout: n_steps must be >= 1, got {n_steps}")
    return rollout_jit(
        model,
        params,
        stats,
        jnp.asarray(x0_prev, jnp.float32),
        jnp.asarray(x0, jnp.float32),
        jnp.asarray(node_type, jnp.int32),
        jnp.asarray(mask, bool),
        int(n_steps),
    )


def rollout(
    model: Any,
    params: Any,
    stats: TargetStats,
    x0_prev: jax.Array,
    x0: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    n_steps: int,
) -> jax.Array:
    """Autoregressive rollout as one ``jax.lax.scan`` over :func:`rollout_step`.

    Compiled once per (model, node count, ``n_steps``): a second call with new positions
    or parameters of the same shapes reuses the compiled program. Works on any fixed node
    set: the full resolution cloud or a subset kept for the whole rollout
    (:func:`select_subset`).

    Args:
        model, params, stats: the surrogate, its parameters and target statistics.
        x0_prev: ``[n_nodes, 3]`` scaled positions s_{t0-1}.
        x0: ``[n_nodes, 3]`` scaled positions s_{t0}.
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
        n_steps: number of predicted frames (static).
    Returns:
        ``[n_steps, n_nodes, 3]`` predicted s_{t0+1} ... s_{t0+n_steps}; vessel and padded
        nodes equal ``x0`` exactly.
    Raises:
        CapacityOverflowError: a fixed-capacity graph buffer overflowed at some step.
    """
    traj, overflow = rollout_with_overflow(
        model, params, stats, x0_prev, x0, node_type, mask, n_steps
    )
    flags = np.asarray(overflow)
    if flags.any():
        first = int(np.argmax(flags))
        raise CapacityOverflowError(
            f"rollout: the graph of model '{getattr(model, 'name', type(model).__name__)}' "
            f"overflowed its fixed capacity at step {first + 1} of {n_steps}; raise the model "
            "config's capacity (e.g. max_neighbors / cell capacity)"
        )
    return traj


def constant_velocity_rollout(
    x0_prev: np.ndarray, x0: np.ndarray, node_type: np.ndarray, mask: np.ndarray, n_steps: int
) -> np.ndarray:
    """The constant-velocity baseline: ``s_{t0+k} = s_{t0} + k (s_{t0} - s_{t0-1})`` for clot nodes.

    Returns:
        ``[n_steps, n_nodes, 3]`` float32; vessel and padded nodes stay at ``x0``.
    """
    x0 = np.asarray(x0, np.float32)
    v = np.asarray(x0, np.float32) - np.asarray(x0_prev, np.float32)
    moving = (np.asarray(mask, bool) & (np.asarray(node_type) == NodeType.CLOT))[:, None]
    k = np.arange(1, int(n_steps) + 1, dtype=np.float32)[:, None, None]
    return np.where(moving[None], x0[None] + k * v[None], x0[None]).astype(np.float32)


def select_subset(node_type: np.ndarray, n_keep: int, *, seed: int = 0) -> np.ndarray:
    """Choose a fixed random node subset that keeps the clot fraction (the study's 2,048 nodes).

    The number of clot nodes kept is ``round(n_keep * n_clot / n_nodes)`` (at least one,
    at most ``n_clot``); the rest are vessel nodes. Deterministic for a given ``seed``.

    Args:
        node_type: ``[n_nodes]`` NodeType values of the full cloud.
        n_keep: nodes to keep; ``>= n_nodes`` keeps every node.
        seed: RNG seed.
    Returns:
        ``[min(n_keep, n_nodes)]`` int64 node indices, sorted.
    """
    node_type = np.asarray(node_type)
    n = node_type.shape[0]
    if n_keep < 1:
        raise ConfigError(f"select_subset: n_keep must be >= 1, got {n_keep}")
    if n_keep >= n:
        return np.arange(n)
    clot = np.flatnonzero(node_type == NodeType.CLOT)
    vessel = np.flatnonzero(node_type != NodeType.CLOT)
    n_clot = int(np.clip(round(n_keep * clot.size / n), min(1, clot.size), clot.size))
    n_clot = max(n_clot, n_keep - vessel.size)
    rng = np.random.default_rng(seed)
    keep = np.concatenate([
        rng.choice(clot, n_clot, replace=False),
        rng.choice(vessel, n_keep - n_clot, replace=False),
    ])
    return np.sort(keep)
