"""Training noise on the inputs with the target corrected (MeshGraphNets' recipe).

Pfaff et al. (2021), DeepMind ``meshgraphnets`` cloth model: Gaussian noise ``n`` of standard
deviation ``std`` is added to the current positions s_t of the moving (clot) nodes only (the vessel
is rigid and known exactly), and the target s_{t+1} is moved by ``(1 - gamma) n``. The model then
sees the corrupted velocity ``v_t + n`` and learns the acceleration
``a' = a - (1 + gamma) n``: ``gamma = 1`` teaches it to remove the whole position error,
``gamma = 0`` to keep the perturbed position but correct the velocity. Defaults: ``std = 0``
(noise off: the study trained without it, so our numbers compare with its table) and
``gamma = 0.1`` (MeshGraphNets' cloth value) when it is switched on. ``std`` is in scaled
coordinates.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.types import clot_mask

__all__ = ["add_training_noise"]


def add_training_noise(
    key: jax.Array,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    std: float,
    gamma: float = 0.1,
    current: int = 1,
    walk: bool = False,
) -> jax.Array:
    """Corrupt s_t of one window and correct its targets s_{t+1}, s_{t+2}, ...

    With one input velocity this is also learning-to-simulate's random-walk noise (the position
    noise of the earliest input frame is 0, of the last one ``N(0, std)``); its target correction
    is ``gamma = 0``. Later frames of a longer window (k-step loss) are shifted like s_{t+1}.

    Args:
        key: PRNG key.
        frames: ``[W, n_nodes, 3]`` the window (s_{t-1}, s_t, s_{t+1}, ...), scaled coordinates.
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
        std: noise standard deviation (0 returns ``frames`` unchanged).
        gamma: fraction of the noise the model learns to remove from the next position.
        current: index of s_t in the window (the step's ``history``: the earlier frames are
            its inputs and stay exact unless ``walk``).
        walk: with ``current = H > 1``, learning-to-simulate's random walk over the whole
            history instead: the H input velocities v_{t-H+1} .. v_t get cumulative Gaussian
            increments of std ``std / sqrt(H)`` (the last one's noise has std ``std``), the
            frames s_{t-H+1} .. s_t their integral (s_{t-H} exact), and the later frames are
            shifted by ``(1 - gamma)`` of s_t's noise: the model learns to remove the whole
            velocity error and ``gamma`` of the position error, from inputs that are all
            corrupted as a rollout corrupts them. ``H = 1`` is the same either way.
    Returns:
        ``[W, n_nodes, 3]`` the noisy window (s_{t-1}, s_t + n, s_{t+1} + (1 - gamma) n, ...).
    """
    if std == 0.0:
        return frames
    moving = clot_mask(node_type, mask)[:, None]
    if walk and current > 1:
        steps = std / jnp.sqrt(current) * jax.random.normal(
            key, (current, *frames.shape[1:]), frames.dtype)
        walked = jnp.where(moving[None], jnp.cumsum(jnp.cumsum(steps, axis=0), axis=0), 0.0)
        frames = frames.at[1:current + 1].add(walked)
        return frames.at[current + 1:].add((1.0 - gamma) * walked[-1])
    noise = jnp.where(moving, std * jax.random.normal(key, frames.shape[1:], frames.dtype), 0.0)
    return frames.at[current].add(noise).at[current + 1:].add((1.0 - gamma) * noise)
