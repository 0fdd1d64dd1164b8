"""The kinematics of the learned step: the model input of a frame, the acceleration target,
the second-order update and the history features (:mod:`thrombojax.simulator.step` uses them
and re-exports them)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.types import ModelInput, clot_mask

__all__ = ["make_input", "target_acceleration", "integrate", "past_accelerations"]


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
    """The update the models learn: ``a_t = s_{t+1} - 2 s_t + s_{t-1}``, ``[..., n_nodes, 3]``."""
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
    moving = clot_mask(node_type, mask)
    return jnp.where(moving[:, None], x_cur + (x_cur - x_prev) + accel, x_cur)


def past_accelerations(x_prev: jax.Array, x_cur: jax.Array, mask: jax.Array,
                       scale: jax.Array | float) -> jax.Array:
    """The history features: ``[n_nodes, 3 (H - 1)]`` accelerations ``a_{t-H+1} .. a_{t-1}`` of
    the frames ``x_prev [H, n_nodes, 3]`` (oldest first) and ``x_cur``, divided by ``scale``,
    zero on padded nodes (and on the rigid vessel, whose acceleration is zero)."""
    frames = jnp.concatenate([x_prev, x_cur[None]])
    acc = target_acceleration(frames[:-2], frames[1:-1], frames[2:]) / scale  # [H - 1, N, 3]
    acc = jnp.where(mask[None, :, None], acc, 0.0)
    return jnp.moveaxis(acc, 0, 1).reshape(x_cur.shape[0], -1)
