"""Masked losses over the real clot nodes of one sample (the vessel is rigid, never predicted).

Two numbers per sample, both averaged over the clot nodes and over x, y, z:

* ``loss``: the training objective, the MSE of the model output against the *normalised*
  acceleration ``TargetStats.normalize(s_{t+1} - 2 s_t + s_{t-1})``: every axis has unit
  variance, so the loss scale does not depend on the dataset's time step (MeshGraphNets /
  learning-to-simulate convention).
* ``mse``: the study's metric (PAPER.md), the MSE of the integrated prediction of s_{t+1}
  against the true s_{t+1} in scaled [-1, 1] coordinates. It equals the loss weighted by
  ``std**2`` per axis, so both have the same minimiser; ``mse`` is what the study's table reports
  and what selects the best checkpoint.

Sums and counts are returned (not means) so a batch, possibly split over devices, pools all its
clot nodes: ``sum(sq) / sum(count)``.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from thrombojax.rollout import integrate, make_input, target_acceleration
from thrombojax.types import TargetStats

__all__ = ["sample_loss_terms", "masked_mse"]


def masked_mse(pred: jax.Array, target: jax.Array, mask: jax.Array) -> jax.Array:
    """MSE over the masked nodes, averaged over the last axis.

    Args:
        pred, target: ``[n_nodes, d]``. mask: ``[n_nodes]`` bool.
    Returns:
        ``[]`` float32 (0 when the mask is empty).
    """
    sq = jnp.where(mask[:, None], (pred - target) ** 2, 0.0)
    return sq.sum() / (jnp.maximum(mask.sum(), 1) * pred.shape[-1])


def sample_loss_terms(
    model: Any,
    params: Any,
    stats: TargetStats,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    train: bool,
    rng: jax.Array | None,
) -> dict[str, jax.Array]:
    """Run the model on one window and return summed squared errors over its clot nodes.

    Args:
        model: a surrogate (``build_graph``, ``apply``).
        params: its parameters.
        stats: acceleration normalisation statistics.
        frames: ``[3, n_nodes, 3]`` (s_{t-1}, s_t, s_{t+1}) scaled.
        node_type: ``[n_nodes]`` NodeType. mask: ``[n_nodes]`` real nodes.
        train: model in training mode (dropout); rng: its PRNG key.
    Returns:
        ``{"loss_sum", "mse_sum", "count", "overflow"}``: squared errors summed over clot nodes
        and averaged over x, y, z; the number of clot nodes; the graph overflow flag.
    """
    x_prev, x_cur, x_next = frames[0], frames[1], frames[2]
    inputs = make_input(x_prev, x_cur, node_type, mask, stats.velocity_std)
    graph = model.build_graph(inputs)
    out = model.apply(params, inputs, graph, train=train, rng=rng)
    target = stats.normalize(target_acceleration(x_prev, x_cur, x_next))
    clot = inputs.clot_mask
    x_pred = integrate(x_prev, x_cur, stats.denormalize(out), node_type, mask)
    loss_sq = jnp.where(clot[:, None], (out - target) ** 2, 0.0).mean(axis=-1)
    mse_sq = jnp.where(clot[:, None], (x_pred - x_next) ** 2, 0.0).mean(axis=-1)
    overflow = _graph_overflow(graph)
    return {
        "loss_sum": loss_sq.sum(),
        "mse_sum": mse_sq.sum(),
        "count": clot.sum().astype(jnp.float32),
        "overflow": overflow,
    }


def _graph_overflow(graph: Any) -> jax.Array:
    """The graph's overflow flag (any leaf named ``overflow``), False when it has none."""
    flag = graph.get("overflow") if isinstance(graph, dict) else getattr(graph, "overflow", None)
    if flag is None:
        return jnp.zeros((), bool)
    return jnp.any(jnp.asarray(flag))
