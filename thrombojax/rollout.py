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

from thrombojax.types import ModelInput, NodeType, TargetStats

__all__ = ["make_input", "target_acceleration", "integrate", "predict_next"]


def make_input(
    x_prev: jax.Array, x_cur: jax.Array, node_type: jax.Array, mask: jax.Array
) -> ModelInput:
    """Build the model input of one frame.

    Args:
        x_prev: ``[n_nodes, 3]`` positions s_{t-1} (scaled).
        x_cur: ``[n_nodes, 3]`` positions s_t (scaled).
        node_type: ``[n_nodes]`` int NodeType values.
        mask: ``[n_nodes]`` bool, True for real nodes.
    Returns:
        The :class:`ModelInput` with velocity ``s_t - s_{t-1}`` (zero on padded nodes).
    """
    velocity = jnp.where(mask[:, None], x_cur - x_prev, 0.0)
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
    inputs = make_input(x_prev, x_cur, node_type, mask)
    graph = model.build_graph(inputs)
    out = model.apply(params, inputs, graph, train=train, rng=rng)
    accel = stats.denormalize(out)
    return integrate(x_prev, x_cur, accel, node_type, mask), out
