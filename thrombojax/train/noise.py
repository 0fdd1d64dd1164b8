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
    Returns:
        ``[W, n_nodes, 3]`` the noisy window (s_{t-1}, s_t + n, s_{t+1} + (1 - gamma) n, ...).
    """
    if std == 0.0:
        return frames
    moving = clot_mask(node_type, mask)[:, None]
    noise = jnp.where(moving, std * jax.random.normal(key, frames.shape[1:], frames.dtype), 0.0)
    return frames.at[1].add(noise).at[2:].add((1.0 - gamma) * noise)
