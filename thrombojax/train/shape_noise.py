"""Swell and stretch noise: the clot's shape scaled about its centroid in the inputs, the target
pulled back.

Why: rolled out alone, the ladder's BendVessel models of the default recipe swell. Teacher-forced
(each step from the true frame) the clot stays inside the vessel, but over a rollout its nodes
spread from the centroid: the least-squares scale of the predicted clot about its centroid
against the true one is 1.007 after one step, 1.045 after three and 1.14 after six (a 7-epoch
model of the recipe, every held-out simulation alike), which is most of the clot that leaves
the vessel without the guards (the centroid-aligned share outside is 23-26 % at step 6 against
33-34 % unaligned). The swelling grows like a velocity the step keeps: no training window shows
a clot larger than its true shape, so the step never learned to take a swelling back. The
Gaussian noise of :mod:`thrombojax.train.noise` is per node (averaged away by message passing)
or a clot-wide shift, and does not perturb this mode.

The noise (:func:`add_swell_noise`): two numbers per window, the swelling ``e ~ N(0, std^2)``
and its rate ``rho ~ N(0, (std / 2)^2)``, independent; the clot of input frame ``j``
(``0 .. current``, s_t at ``current``) is scaled about its own centroid by
``1 + e - (current - j) rho`` (s_t swollen by ``e``, the input velocities carrying a swelling
rate ``rho`` as a rollout's do), and every later frame (the targets) by ``1 + (1 - gamma) e``:
the model learns to take back ``gamma`` of a swelling in one step (default 1/2, as the wall
noise) and not to keep its rate. The two are drawn apart so that the model must read the
swelling from the clot's shape: with the rate tied to the swelling (a swelling grown steadily
over the input frames) a tiny model learned the pull-back from the input velocities alone and
kept a swelling that came with the true velocities (``tests/test_swell_noise.py``). ``e < 0``
shrinks the clot, which the model learns to undo as well. The centroid and its motion are
unchanged.

:func:`thrombojax.eval.drift.swell_carry` measures how much of a swelling in its inputs a step
keeps (constant velocity: all of it, 1).

The stretch noise (:func:`add_stretch_noise`) is the same draw applied along one direction only:
the clot's mean motion into s_t. Why: rolled out alone, the vessel-frame BendVessel models keep
their clot's rear near the true rear while its front runs ahead, up to 6 r past the true front
before the exit (the true clot keeps its 2.8 r length), and the centroid follows the front
(``experiments/results/ladder_budget/bendvessel_shapes/exit/README.md``); the isotropic swell
noise does not show that mode. The clot of input frame ``j`` is stretched along the motion
``d`` by ``1 + e - (current - j) rho`` (the front moving faster than the rear, as in such a
rollout), the targets by ``1 + (1 - gamma) e``; offsets across ``d`` and the centroid stay.
``drift.swell_carry(..., along_motion=True)`` measures the share of a stretch a step keeps.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.graph.clot_shape import clot_motion
from thrombojax.train.noise import noise_off
from thrombojax.types import clot_mask

__all__ = ["add_stretch_noise", "add_swell_noise", "scale_about_centroid"]


def scale_about_centroid(points: jax.Array, moving: jax.Array, factor: jax.Array,
                         direction: jax.Array | None = None) -> jax.Array:
    """The ``moving`` nodes of ``points [..., n_nodes, 3]`` scaled by ``factor [...]`` about
    their centroid (the mean over ``moving`` of each frame); the other nodes as given. With a
    unit (or zero) vector ``direction [3]``, only each offset's component along it is scaled
    (a stretch; a zero direction changes nothing)."""
    w = moving.astype(points.dtype)[:, None]
    centre = jnp.sum(points * w, axis=-2, keepdims=True) / jnp.maximum(jnp.sum(w), 1.0)
    offset = points - centre
    if direction is not None:
        offset = jnp.sum(offset * direction, axis=-1, keepdims=True) * direction
    scaled = points + (factor[..., None, None] - 1.0) * offset
    return jnp.where(moving[:, None], scaled, points)


def _shape_factors(key, frames, std, current, gamma, what):
    """Per window frame: ``1 + e - (current - j) rho`` up to s_t, ``1 + (1 - gamma) e`` after."""
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"{what} gamma must be in [0, 1], got {gamma!r}")
    if current < 1:
        raise ValueError(f"{what} needs s_t at index >= 1 of the window, got {current!r}")
    e, rho = std * jax.random.normal(key, (2,), frames.dtype) * jnp.array([1.0, 0.5],
                                                                           frames.dtype)
    j = jnp.arange(frames.shape[0], dtype=frames.dtype)
    return jnp.where(j <= current, 1.0 + e - (current - j) * rho, 1.0 + (1.0 - gamma) * e)


def add_swell_noise(
    key: jax.Array,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    std: float,
    current: int,
    gamma: float = 0.5,
) -> jax.Array:
    """Swell (or shrink) the clot of one window about its centroid (module docstring).

    Args:
        key: PRNG key.
        frames: ``[W, n_nodes, 3]`` the window, scaled coordinates; ``frames[current]`` is s_t.
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
        std: standard deviation of ``e``, a fraction of the clot's size (dimensionless; 0
            returns ``frames`` unchanged).
        current: index of s_t in the window (the step's ``history``, >= 1).
        gamma: share of the swelling the model learns to take back in one step, in ``[0, 1]``.
    Returns:
        ``[W, n_nodes, 3]``: the clot of frame ``j <= current`` scaled about its centroid by
        ``1 + e - (current - j) rho``, of every later frame by ``1 + (1 - gamma) e``; vessel
        and padded nodes as given.
    Raises:
        ValueError: a negative ``std``, ``gamma`` outside ``[0, 1]`` or ``current < 1``.
    """
    if noise_off(std, "swell noise"):
        return frames
    factor = _shape_factors(key, frames, std, current, gamma, "swell noise")
    return scale_about_centroid(frames, clot_mask(node_type, mask), factor)


def add_stretch_noise(
    key: jax.Array,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    std: float,
    current: int,
    gamma: float = 0.5,
) -> jax.Array:
    """Stretch (or squeeze) the clot of one window along its motion (module docstring).

    The direction is the clot's mean displacement from ``frames[current - 1]`` to
    ``frames[current]``, normalised (zero for a clot at rest: nothing changes), the same for
    every frame of the window. Arguments, returns and errors as :func:`add_swell_noise`, the
    factor applied along that direction only.
    """
    if noise_off(std, "stretch noise"):
        return frames
    factor = _shape_factors(key, frames, std, current, gamma, "stretch noise")
    moving = clot_mask(node_type, mask)
    _, direction = clot_motion(frames[current - 1], frames[current], moving)
    return scale_about_centroid(frames, moving, factor, direction)
