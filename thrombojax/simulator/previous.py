"""The frames before t a learned step reads (its ``x_prev``), as pure functions.

A :class:`~thrombojax.simulator.step.LearnedStep` with ``history = H`` reads the ``H`` frames
``s_{t-H} .. s_{t-1}``; with ``rest_edges`` it also reads the clot's rest state, the
simulation's first frame (the clot before it is driven), which its model compares the current
edges with (rest-state edge displacements, as DeepMind's deforming-plate MeshGraphNet). The
step's ``x_prev`` is then:

=================  ===================  =============================================
history            rest_edges False     rest_edges True
=================  ===================  =============================================
1                  ``[N, 3]`` s_{t-1}    ``[2, N, 3]`` (rest, s_{t-1})
H >= 2             ``[H, N, 3]``         ``[1 + H, N, 3]`` (rest, s_{t-H} .. s_{t-1})
=================  ===================  =============================================

(leading batch axes allowed). With ``start_speed = K`` (an int >= 1; ``True`` is 1) the step also
reads the two frames of the clot's start speed, ``s_{c-K}, s_c`` with ``c`` the frame a rollout
starts from and frames before 0 frame 0 (after the rest frame, before the history;
:mod:`thrombojax.simulator.start_speed`). A rollout carries
``x_prev`` from step to step with :func:`shift`, which keeps these lead frames and moves the
others on, so every consumer of the step (rollouts, ensembles, the unrolled loss, evaluation)
passes them along without knowing they are there.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.data.windows import start_pair
from thrombojax.errors import ConfigError

__all__ = ["previous", "lead_with_rest", "last_previous", "history_frames", "rest_frame",
           "start_frames", "shift", "previous_shape", "lead_count"]


def lead_count(rest: bool, start_speed: bool = False) -> int:
    """Frames an ``x_prev`` holds before its history: the rest frame, then two start frames."""
    return int(rest) + 2 * bool(start_speed)


def _stacked(history: int, rest: bool, start_speed: bool = False) -> bool:
    return history > 1 or rest or bool(start_speed)


def previous(history: int, rest: bool, positions, t, rest_positions=None, *, start_speed=False,
             start_from=None):
    """The ``x_prev`` of frame(s) ``t`` of a trajectory ``positions [T, N, 3]``.

    Frames before 0 are frame 0 (the clot at rest before the record starts). ``t`` is an int or
    an int array, every ``t >= 1``. The rest frame is ``positions[0]`` (a trajectory from its
    first frame) and the start frames (``start_speed`` K) are ``s_{c-K}, s_c`` with ``c = min(t,
    start_from)`` (``start_from`` None: ``c = t``, a rollout from ``t``), unless
    ``rest_positions`` (``[L, N, 3]``, the :func:`lead_count` lead frames; ``[N, 3]`` the rest
    frame alone) is given: a training window, which starts later. It is broadcast over the
    axes of ``t``.
    """
    t = np.asarray(t)
    if np.any(t < 1):
        raise ConfigError(f"learned step: frame t = {t.min()} has no previous frame (t >= 1)")
    if not _stacked(history, rest, start_speed):
        return positions[t - 1]
    if t.ndim == 0 and t >= history:  # a slice (also of a traced window)
        frames = positions[int(t) - history:int(t)]
    else:
        frames = positions[np.maximum(t[..., None] + np.arange(-history, 0), 0)]
    if not (rest or start_speed):
        return frames
    if rest_positions is not None:
        return lead_with_rest(rest_positions, frames)
    if start_speed:
        pair = np.stack(start_pair(t, start_from, int(start_speed)), axis=-1)
        frames = lead_with_rest(positions[pair], frames)
    return lead_with_rest(positions[0], frames) if rest else frames


def lead_with_rest(rest_positions, frames):
    """The ``x_prev`` of lead frames (a rest frame ``[N, 3]``, or ``[..., L, N, 3]``) and the
    frames before t (``[..., H, N, 3]``; ``[N, 3]`` is one frame): the lead frames broadcast
    over the leading axes and put first. numpy in, numpy out."""
    xp = np if isinstance(frames, np.ndarray) and isinstance(rest_positions, np.ndarray) else jnp
    if frames.ndim == 2:
        frames = frames[None]
    if rest_positions.ndim == 2:
        rest_positions = rest_positions[None]
    ref = xp.broadcast_to(rest_positions, frames.shape[:-3] + rest_positions.shape[-3:])
    return xp.concatenate([ref.astype(frames.dtype), frames], axis=-3)


def last_previous(history: int, rest: bool, x_prev: jax.Array,
                  start_speed: bool = False) -> jax.Array:
    """s_{t-1} of an ``x_prev``."""
    return x_prev[..., -1, :, :] if _stacked(history, rest, start_speed) else x_prev


def history_frames(history: int, rest: bool, x_prev: jax.Array,
                   start_speed: bool = False) -> jax.Array:
    """The frames before t without the lead frames (``[H, N, 3]``, or ``[N, 3]`` for H = 1)."""
    lead = lead_count(rest, start_speed)
    if not lead:
        return x_prev
    return x_prev[..., lead:, :, :] if history > 1 else x_prev[..., lead, :, :]


def start_frames(rest: bool, x_prev: jax.Array) -> jax.Array:
    """The two start frames ``[..., 2, N, 3]`` of a step's ``x_prev`` that reads them."""
    return x_prev[..., int(rest):int(rest) + 2, :, :]


def rest_frame(rest: bool, x_prev: jax.Array) -> jax.Array | None:
    """The rest frame of an ``x_prev`` (None when the step reads none)."""
    return x_prev[..., 0, :, :] if rest else None


def shift(history: int, rest: bool, x_prev: jax.Array, x_cur: jax.Array,
          start_speed: bool = False) -> jax.Array:
    """The ``x_prev`` of the next step: the lead frames kept, the others moved on by ``x_cur``."""
    if not _stacked(history, rest, start_speed):
        return x_cur
    keep = lead_count(rest, start_speed)
    moved = x_prev[..., keep + 1:, :, :] if history > 1 else x_prev[..., :0, :, :]
    parts = [x_prev[..., :keep, :, :], moved, x_cur[..., None, :, :]]
    return jnp.concatenate(parts, axis=-3)


def previous_shape(history: int, rest: bool, n_nodes: int,
                   start_speed: bool = False) -> tuple[int, ...]:
    """The shape of one ``x_prev`` (no batch axes)."""
    if not _stacked(history, rest, start_speed):
        return (n_nodes, 3)
    return (history + lead_count(rest, start_speed), n_nodes, 3)
