"""The clot's start speed: how fast the clot moved into the true frame a rollout starts from.

A learned step with ``start_speed`` (``make_step(model, start_speed=True)``, ``thrombojax train
--start-speed``) also reads two true frames, ``s_{c-1}`` and ``s_c``, where ``c`` is the frame
its rollout starts from, and gives every clot node one number: the clot centroid's speed
between them, divided by the velocity scale of the step's inputs (:func:`start_speed_feature`).
A rollout keeps those two frames from its first step to its last
(:func:`thrombojax.simulator.previous.shift`), so the number never drifts with the model's own
output, while the velocity the step reads does.

Why: the solver's clot reaches its terminal speed within a frame, and that speed is set per
simulation by its drive, damping and friction. A step trained to take its speed from the
vessel (speed noise, the ``room`` and ``outlet`` recipes) forgets the speed it is shown and
runs every simulation at the training simulations' pace; a step that keeps the speed it is
shown (constant velocity) keeps its own errors too. The start speed is the simulation's speed
from true frames, which a rollout has (it starts from them) and which does not carry the
rollout's errors. The training windows read it the same way: ``c = min(t, T0)`` for a window at
frame ``t``, ``T0`` the frame the dataset's rollouts start from (its ``skip_frames``,
:func:`thrombojax.study.skip_frames`), so a window in the rollout phase reads the start speed of
the rollout's start, and one before it (the start from rest) its own true velocity
(``start_speed`` of :func:`thrombojax.data.batching.make_batch`; for the one-step evaluation,
``start_from`` of :func:`thrombojax.simulator.previous.previous`).

Measured (``experiments/results/ladder_budget/start_speed/README.md``): on BendVessel, whose
clots slide at their terminal speed from the rollout's start, four seeds of four end a little
nearer guarded, the exit's lag unchanged; on ClotEntry, whose clots enter at a speed that says
nothing of their pace, the models end farther off. Off by default.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.types import clot_mask

__all__ = ["start_speed_feature"]


def start_speed_feature(start_frames: jax.Array, node_type: jax.Array, mask: jax.Array,
                        velocity_scale) -> jax.Array:
    """``[N, 1]``: the speed of the real clot nodes' centroid from ``start_frames[0]`` to
    ``start_frames[1]`` (``[2, N, 3]``) divided by ``velocity_scale``, on every real clot node;
    zeros on every other node. Invariant to rotations and translations. Jittable."""
    clot = clot_mask(node_type, mask)
    w = clot.astype(start_frames.dtype)[:, None]
    count = jnp.maximum(jnp.sum(w), 1.0)
    velocity = jnp.sum((start_frames[1] - start_frames[0]) * w, axis=0) / count
    speed = jnp.sqrt(jnp.sum(velocity ** 2) + 1e-20) / velocity_scale
    return jnp.where(clot, speed, 0.0)[:, None]
