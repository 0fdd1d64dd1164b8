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

The start span (``thrombojax train --start-speed --start-span K``, ``make_step(model,
start_speed=K)``): the two frames are ``s_{c-K}, s_c`` instead (frames before 0 are frame 0,
the clot at rest) and the feature is the centroid's mean speed over those K frames. With ``K``
the rollout's start frame ``T0`` it is the clot's travel from rest to the rollout's start over
``T0``: how soon the clot broke free, which the drive ratio sets (the drive ramps up and the
clot moves once it beats the friction's hold) and which also sets how much faster the clot
leaves the vessel than it slid through it (on BendVessel the travel by frame 5 correlates 0.81
with that speed-up over the 20 simulations, the speed at frame 5 -0.41;
``experiments/results/ladder_budget/start_span/README.md``). A window before ``T0`` reads its
travel from rest over ``K`` frames, not its own speed. Measured there: the BendVessel steps do
not use it for the exit (guarded as without the start speed) and on ClotEntry it takes back
what the start speed cost (two draws of four seeds 0.70 and 1.17 r held out). Off by default.

Start-speed noise (``thrombojax train --start-speed-noise F``, :func:`jitter_start_speed`): in
training, every window's start speed is scaled by ``1 + e``, ``e ~ N(0, F^2)``, so that a step
cannot tell its few training simulations apart by their start speeds and learns only what the
start speed says of the pace on average. Measured at ``F = 0.3``
(``experiments/results/ladder_budget/start_speed_noise/README.md``): the BendVessel steps then
read none of the start speed and the ClotEntry ones a fifth of it, and ClotEntry still ends
farther off than without the start speed. Off by default.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.types import clot_mask

__all__ = ["start_speed_feature", "scale_start_speed", "jitter_start_speed"]


def start_speed_feature(start_frames: jax.Array, node_type: jax.Array, mask: jax.Array,
                        velocity_scale) -> jax.Array:
    """``[N, 1]``: the speed of the real clot nodes' centroid from ``start_frames[0]`` to
    ``start_frames[1]`` (``[2, N, 3]``) divided by ``velocity_scale`` (times the frames between
    them for a mean speed), on every real clot node;
    zeros on every other node. Invariant to rotations and translations. Jittable."""
    clot = clot_mask(node_type, mask)
    w = clot.astype(start_frames.dtype)[:, None]
    count = jnp.maximum(jnp.sum(w), 1.0)
    velocity = jnp.sum((start_frames[1] - start_frames[0]) * w, axis=0) / count
    speed = jnp.sqrt(jnp.sum(velocity ** 2) + 1e-20) / velocity_scale
    return jnp.where(clot, speed, 0.0)[:, None]


def scale_start_speed(x_prev: jax.Array, factor, rest: bool = False) -> jax.Array:
    """``x_prev`` (a step's, or a window's lead frames) with its start frame ``s_c`` moved to
    ``s_{c-1} + factor (s_c - s_{c-1})``: every node's start motion, and so the clot's start
    speed (:func:`start_speed_feature`), scaled by ``|factor|``; every other frame unchanged.
    The start frames follow the rest frame when ``rest``
    (:func:`thrombojax.simulator.previous.start_frames`). Jittable."""
    x_prev = jnp.asarray(x_prev)
    before, start = x_prev[..., int(rest), :, :], x_prev[..., int(rest) + 1, :, :]
    return x_prev.at[..., int(rest) + 1, :, :].set(before + factor * (start - before))


def jitter_start_speed(key: jax.Array, lead: jax.Array, std: float) -> jax.Array:
    """A window's lead frames ``lead`` (``[L, N, 3]``, the two start frames ``s_{c-1}, s_c``
    last) with the start speed scaled by ``1 + e``, ``e ~ N(0, std^2)`` one draw
    (:func:`scale_start_speed`); the other lead frames unchanged. ``std = 0`` returns ``lead``
    itself. Jittable (``std`` static)."""
    if not std >= 0:
        raise ValueError(f"start-speed noise: std must be >= 0, got {std!r}")
    if std == 0:
        return lead
    if lead.ndim != 3 or lead.shape[0] < 2:
        raise ValueError(f"start-speed noise needs the lead frames [L >= 2, N, 3] with the two "
                         f"start frames last, got shape {tuple(lead.shape)}")
    factor = 1.0 + std * jax.random.normal(key, (), lead.dtype)
    return scale_start_speed(lead, factor, rest=lead.shape[0] > 2)  # 3 frames: rest first
