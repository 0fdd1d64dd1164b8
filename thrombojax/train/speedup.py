"""The clot's speed over a training window, and the loss weight of windows where it speeds up.

A BendVessel clot slides along the vessel at a near-constant speed until it leaves through the
outlet, where its speed rises by up to 2.5 vessel radii over a few frames. Few training windows
hold that exit, and a step trained on all windows alike learns to brake there, where the truth
speeds up (``experiments/results/ladder_budget/bendvessel_exit/README.md``).
:func:`speedup_window_weight` gives such windows a larger share of the loss: a window whose
true clot centroid moves faster from s_t to s_{t+1} than ``1 + fraction`` times its speed from
s_{t-1} to s_t (a clot at rest that starts to move counts) weighs ``1 + weight``, every other
window 1. It reads the clean frames, before any input noise, and only the target frame s_{t+1}
of the first step of the window. The weight is a training-time choice of which windows count
more: using the target frame is allowed there and never happens in a rollout.

:func:`clot_speeds` is also what the speed noise's steady gate reads
(:func:`thrombojax.train.noise.add_speed_noise`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.types import clot_mask

__all__ = ["clot_speeds", "speedup_window_weight"]


def clot_speeds(frames: jax.Array, node_type: jax.Array, mask: jax.Array,
                current: int) -> tuple[jax.Array, jax.Array]:
    """The clot centroid's speeds ``(|c_t - c_{t-1}|, |c_{t+1} - c_t|)`` in one window.

    Args:
        frames: ``[W, N, 3]`` positions; s_t at index ``current``.
        node_type, mask: ``[N]`` node types and the real-node mask (padding excluded).
        current: index of s_t; needs ``1 <= current <= W - 2`` (ValueError otherwise).

    Returns:
        Two scalars, the speeds in the frames' units per frame.
    """
    if not 1 <= current <= frames.shape[0] - 2:
        raise ValueError(f"the clot's speeds need s_(t-1), s_t and s_(t+1) around index "
                         f"{current} of a window of {frames.shape[0]} frames")
    w = clot_mask(node_type, mask).astype(frames.dtype)[:, None]
    centroid = (frames[current - 1:current + 2] * w).sum(axis=1) / jnp.maximum(w.sum(), 1.0)
    before = jnp.linalg.norm(centroid[1] - centroid[0])
    after = jnp.linalg.norm(centroid[2] - centroid[1])
    return before, after


def speedup_window_weight(frames: jax.Array, node_type: jax.Array, mask: jax.Array, *,
                          current: int, weight: float, fraction: float) -> jax.Array:
    """The loss weight of one training window: ``1 + weight`` where the clot speeds up, else 1.

    Args:
        frames: ``[W, N, 3]`` clean positions (no input noise); s_t at index ``current``.
        node_type, mask: ``[N]`` node types and the real-node mask.
        current: index of s_t (the step's history).
        weight: the extra weight (``>= 0``).
        fraction: the window speeds up where ``|c_{t+1} - c_t| > (1 + fraction) |c_t - c_{t-1}|``
            (``>= 0``).

    Returns:
        A scalar of the frames' dtype.
    """
    if weight < 0 or fraction < 0:
        raise ValueError(f"the speed-up weight and fraction must be >= 0, got {weight!r} and "
                         f"{fraction!r}")
    before, after = clot_speeds(frames, node_type, mask, current)
    faster = after > (1.0 + fraction) * before
    return jnp.where(faster, 1.0 + weight, 1.0).astype(frames.dtype)
