"""How a rollout drifts: the clot's speed per step and the history gain of a learned step.

A rollout whose clot ends radii from the true one has usually not gone the wrong way but at the
wrong speed: on the ladder's BendVessel models the true clot slides at a steady speed until it
leaves the vessel, while the rollout speeds up a little every step. Two measures say so:

- :func:`centroid_speed`: the distance the clot's centroid moves per frame, for a rollout and
  for the truth side by side;
- :func:`history_gain`: of a change of the clot-wide acceleration in a step's history (the
  frames before s_{t-1} moved back along the motion, s_{t-1} and s_t as they are), the share
  the step's predicted acceleration carries over. In a rollout the history is the step's own
  output, so a gain ``g`` multiplies every small acceleration error by about ``1 / (1 - g)``,
  and the speed, which nothing in the inputs pins (the terminal speed is not an input),
  integrates it. The physics carries nothing over once the drive has ramped up (the
  acceleration follows from the positions and velocity); the ladder's models of the default
  recipe with wall noise and signed wall features carry about half over (0.47-0.48,
  ``experiments/results/ladder_budget/bendvessel_histnoise/``).
- :func:`speed_carry`: of a clot-wide speed error in the inputs (every frame before s_t moved so
  the clot's input motion reads ``1 + delta`` times the truth), the share the step's predicted
  next motion keeps. Constant velocity keeps all of it (1); a step that keeps all of it cannot
  pull a rollout's speed back, and any bias drifts the speed; below 1 the step brings the speed
  back toward the data's (:func:`thrombojax.train.noise.add_speed_noise` trains that).
- :func:`direction_carry`: of a turn of the clot's input motion (every frame before s_t moved so
  the motion into s_t is rotated by a small angle about an axis across it, the clot now coming
  in across its path), the share of that sideways motion the step's predicted next motion
  keeps. Constant velocity keeps all of it (1); a rollout's clot that drifts off the true track
  keeps drifting with a step near 1 (:func:`thrombojax.train.noise.add_direction_noise` trains
  the pull-back).
- :func:`swell_carry`: of a swelling of the clot in the inputs (the clot of s_t and of every
  frame before it scaled about its centroid by ``1 + delta``), the share the predicted next
  clot keeps (its least-squares scale about its centroid against the prediction from the true
  inputs). Constant velocity keeps all of it (1); a rollout whose clot swells a little in one
  step keeps swelling with a step near 1 and leaves the vessel
  (:func:`thrombojax.train.shape_noise.add_swell_noise` trains the pull-back). With
  ``along_motion=True`` the same for a stretch of the clot along its motion into s_t only (its
  front moved ahead, its rear back: :func:`thrombojax.train.shape_noise.add_stretch_noise`),
  and with ``rate=True`` of a swelling or stretching *rate* in the input motion.

All are teacher-forced or post-hoc measures on host arrays; nothing here is compiled for a
rollout.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from thrombojax.errors import ConfigError
from thrombojax.eval.metrics import clot_centroids
from thrombojax.eval.single_step import batched_next
from thrombojax.simulator.previous import history_frames, lead_count, lead_with_rest
from thrombojax.simulator.step import LearnedStep
from thrombojax.train.noise import rotation_matrix
from thrombojax.types import TargetStats, clot_mask

__all__ = ["centroid_speed", "history_gain", "speed_carry", "direction_carry",
           "swell_carry"]


def centroid_speed(trajectory: np.ndarray, clot_mask: np.ndarray) -> np.ndarray:
    """Distance the clot centroid moves per frame, ``[T - 1]`` (units of ``trajectory``).

    Args:
        trajectory: ``[T, n_nodes, 3]`` frames (a rollout with the frame it started from first,
            or the truth). clot_mask: ``[n_nodes]`` bool, the clot nodes.
    """
    return np.linalg.norm(np.diff(clot_centroids(trajectory, clot_mask), axis=0), axis=-1)


def history_gain(
    step: LearnedStep,
    params: dict,
    stats: TargetStats,
    positions: np.ndarray,
    node_type: np.ndarray,
    frames: np.ndarray,
    *,
    delta: float,
    mask: np.ndarray | None = None,
) -> np.ndarray:
    """Share of a change of the history's clot-wide acceleration a step carries over, per frame.

    At each frame ``t``: the clot nodes of the frames before s_{t-1} are moved back by ``delta``
    along the clot's motion (s_t - s_{t-1} of its centroid), which lowers the history's last
    acceleration ``a_{t-1}`` by ``delta`` and leaves s_{t-1}, s_t and the velocity as they are;
    the gain is how much the predicted centroid acceleration along the motion drops, over
    ``delta``.

    Args:
        step: a learned step with ``history >= 2``. params, stats: its variables and statistics.
        positions: ``[T, n_nodes, 3]`` a trajectory (scaled coordinates). node_type: ``[n_nodes]``.
        frames: the frames ``t`` (each ``>= 1`` and ``< T``) to measure at.
        delta: the change, scaled coordinates (> 0; small against the motion per frame).
        mask: ``[n_nodes]`` real nodes (default: all).
    Returns:
        ``[len(frames)]`` gains (0: nothing carried over; 1: all of it).
    Raises:
        ConfigError: a step without history or with a cell grid, a bad ``delta`` or a clot at
            rest at a frame.
    """
    step.require_dense("history gain")
    if step.history < 2:
        raise ConfigError(f"history gain: the step reads {step.history} previous frame(s); it "
                          "has no history acceleration (needs history >= 2)")
    if not delta > 0:
        raise ConfigError(f"history gain: delta must be > 0, got {delta!r}")

    def move(prev, cur, clot, along, speed):
        moved = prev.copy()
        moved[:-1, clot] -= delta * along
        return moved

    return _per_frame(step, params, stats, positions, node_type, mask, frames, "history gain",
                      move, lambda shift, along, speed: float(-shift @ along) / delta)


def speed_carry(
    step: LearnedStep,
    params: dict,
    stats: TargetStats,
    positions: np.ndarray,
    node_type: np.ndarray,
    frames: np.ndarray,
    *,
    delta: float,
    mask: np.ndarray | None = None,
) -> np.ndarray:
    """Share of a clot-wide speed error in the inputs that a step keeps, per frame.

    At each frame ``t``: the clot nodes of every frame before s_t are moved to
    ``s_t - (1 + delta) (s_t - s_k)`` (the clot's input motion reads ``1 + delta`` times the
    truth; s_t as it is); the share is how much the predicted centroid motion along the clot's
    motion grows, over ``delta`` times the clot's speed. 1: the error is kept (constant velocity);
    0: the step brings the speed back to what it predicts from the true inputs in one step.

    Args:
        step: a learned step. params, stats: its variables and statistics.
        positions: ``[T, n_nodes, 3]`` a trajectory (scaled coordinates). node_type: ``[n_nodes]``.
        frames: the frames ``t`` (each ``>= step.history`` and ``< T``) to measure at.
        delta: the relative speed error (> 0; small, e.g. 0.05).
        mask: ``[n_nodes]`` real nodes (default: all).
    Returns:
        ``[len(frames)]`` shares.
    Raises:
        ConfigError: a step with a cell grid, a bad ``delta`` or a clot at rest at a frame.
    """
    step.require_dense("speed carry")
    if not delta > 0:
        raise ConfigError(f"speed carry: delta must be > 0, got {delta!r}")

    def move(prev, cur, clot, along, speed):
        moved = prev.copy()
        moved[:, clot] = cur[None, clot] - (1.0 + delta) * (cur[None, clot] - prev[:, clot])
        return moved

    return _per_frame(step, params, stats, positions, node_type, mask, frames, "speed carry",
                      move, lambda shift, along, speed: float(shift @ along) / (delta * speed))


def direction_carry(
    step: LearnedStep,
    params: dict,
    stats: TargetStats,
    positions: np.ndarray,
    node_type: np.ndarray,
    frames: np.ndarray,
    *,
    angle: float,
    mask: np.ndarray | None = None,
) -> np.ndarray:
    """Share of a sideways turn of the clot's input motion that a step keeps, per frame.

    At each frame ``t`` and for each of two axes across the clot's motion (``u`` its centroid's
    direction s_t - s_{t-1}; the axes ``a`` and ``u x a``): the clot nodes of every frame before
    s_t are moved to ``s_t - R (s_t - s_k)``, ``R`` the rotation by ``angle`` about the axis
    (the clot comes into s_t moving sideways at ``speed sin(angle)``, s_t as it is); the share
    is how far the predicted next centroid moves along that sideways direction, over
    ``speed sin(angle)``; the two axes' shares are averaged. 1: the sideways motion is kept
    (constant velocity); 0: the step predicts the same next motion as from the true inputs.

    Args:
        step: a learned step. params, stats: its variables and statistics.
        positions: ``[T, n_nodes, 3]`` a trajectory (scaled coordinates). node_type: ``[n_nodes]``.
        frames: the frames ``t`` (each ``>= step.history`` and ``< T``) to measure at.
        angle: the turn, radians (> 0 and < pi / 2; small, e.g. 0.1).
        mask: ``[n_nodes]`` real nodes (default: all).
    Returns:
        ``[len(frames)]`` shares.
    Raises:
        ConfigError: a step with a cell grid, a bad ``angle`` or a clot at rest at a frame.
    """
    step.require_dense("direction carry")
    if not 0.0 < angle < np.pi / 2:
        raise ConfigError(f"direction carry: angle must be in (0, pi/2) radians, got {angle!r}")

    def across(along: np.ndarray, which: int) -> np.ndarray:
        axis = np.cross(along, np.eye(3)[np.argmin(np.abs(along))])
        axis /= np.linalg.norm(axis)
        return axis if which == 0 else np.cross(along, axis)

    def turned(which):
        def move(prev, cur, clot, along, speed):
            rot = np.asarray(rotation_matrix(jnp.asarray(angle * across(along, which))),
                             np.float64)
            moved = prev.copy()
            moved[:, clot] = cur[None, clot] - (cur[None, clot] - prev[:, clot]) @ rot.T
            return moved

        def share(shift, along, speed):
            side = np.cross(across(along, which), along)  # where R turns the motion
            return float(shift @ side) / (speed * np.sin(angle))

        return _per_frame(step, params, stats, positions, node_type, mask, frames,
                          "direction carry", move, share)

    return 0.5 * (turned(0) + turned(1))


def swell_carry(
    step: LearnedStep,
    params: dict,
    stats: TargetStats,
    positions: np.ndarray,
    node_type: np.ndarray,
    frames: np.ndarray,
    *,
    delta: float,
    mask: np.ndarray | None = None,
    along_motion: bool = False,
    rate: bool = False,
) -> np.ndarray:
    """Share of a swelling of the clot in the inputs that a step keeps, per frame.

    At each frame ``t``: the clot of s_t and of every frame before it is scaled about its own
    centroid by ``1 + delta`` (a swollen clot moving as the true one); the share is the
    least-squares scale of the predicted next clot about its centroid against the next clot
    predicted from the true inputs, less 1, over ``delta``. 1: the swelling is kept (constant
    velocity); 0: the step predicts the clot's true shape again in one step.

    Args:
        step: a learned step. params, stats: its variables and statistics.
        positions: ``[T, n_nodes, 3]`` a trajectory (scaled coordinates). node_type: ``[n_nodes]``.
        frames: the frames ``t`` (each ``>= 1`` and ``< T``) to measure at.
        delta: the relative swelling (> 0; small, e.g. 0.02).
        mask: ``[n_nodes]`` real nodes (default: all).
        along_motion: stretch instead: only the offsets' components along the clot's mean
            motion from frame ``t - 1`` to ``t`` are scaled, and the share is measured along it
            (a frame where the clot is at rest gives NaN).
        rate: a swelling rate instead: s_t as it is, the frame ``k`` steps before it scaled
            by ``1 - k delta``, so the input motion carries a swelling of ``delta`` per frame
            and the clot's shape none; the share is of that rate (constant velocity 1 on a
            clot moving as a rigid body, about 1 on a deforming one; 0: the step stops the
            swelling in one step). What the rate ``rho`` of the swell and stretch noise trains.
    Returns:
        ``[len(frames)]`` shares.
    Raises:
        ConfigError: a step with a cell grid or a bad ``delta``.
    """
    step.require_dense("swell carry")
    if not delta > 0:
        raise ConfigError(f"swell carry: delta must be > 0, got {delta!r}")
    positions, node_type, mask, clot = _arrays(positions, node_type, mask)

    def swell(x, d, by):
        centre = x[..., clot, :].mean(axis=-2, keepdims=True)
        rel = x[..., clot, :] - centre
        by = np.reshape(by, np.shape(by) + (1, 1))
        out = x.copy()
        out[..., clot, :] = centre + rel + by * (rel if d is None else (rel @ d)[..., None] * d)
        return out

    def size(offsets, d):  # the offsets whose scale is measured
        return offsets if d is None else offsets @ d

    out = []
    for t in np.asarray(frames, int):
        cur, (rest, given) = positions[t], _split_rest(step, step.previous(positions, t))
        d = None
        if along_motion:
            motion = (positions[t, clot] - positions[t - 1, clot]).mean(axis=0)
            if not np.linalg.norm(motion) > 0:
                out.append(np.nan)
                continue
            d = motion / np.linalg.norm(motion)
        lags = np.arange(step.history, 0, -1) if step.history > 1 else np.asarray(1)
        by_given, by_cur = (-delta * lags, 0.0) if rate else (delta, delta)
        nxt = np.asarray(batched_next(
            step, params, stats, jnp.asarray(np.stack([_join_rest(rest, given), _join_rest(
                rest, swell(given, d, by_given))])),
            jnp.asarray(np.stack([cur, swell(cur, d, by_cur)])), jnp.asarray(node_type),
            jnp.asarray(mask)), np.float64)[:, clot]
        base, pert = (size(o, d) for o in nxt - nxt.mean(axis=1, keepdims=True))
        out.append((float(np.sum(pert * base) / np.sum(base * base)) - 1.0) / delta)
    return np.asarray(out)


def _per_frame(step, params, stats, positions, node_type, mask, frames, what, move, share):
    """For each frame: the step's next centroid from the true inputs and from the inputs
    ``move(prev, cur, clot, along, speed)`` makes (one call of the compiled step for both), and
    ``share(shift of the centroid, along, speed)``."""
    positions, node_type, mask, clot = _arrays(positions, node_type, mask)
    out = []
    for t in np.asarray(frames, int):
        cur, (rest, given) = positions[t], _split_rest(step, step.previous(positions, t))
        prev = given.reshape(-1, *cur.shape)  # [H, n_nodes, 3] (history 1 gives [n_nodes, 3])
        v = cur[clot].mean(axis=0) - prev[-1][clot].mean(axis=0)
        speed = float(np.linalg.norm(v))
        if speed == 0.0:
            raise ConfigError(f"{what}: the clot does not move at frame {t}")
        along = v / speed
        moved = _join_rest(rest, move(prev, cur, clot, along, speed).reshape(given.shape))
        given = _join_rest(rest, given)
        # the window as it is and with the inputs moved, in one call
        nxt = np.asarray(batched_next(step, params, stats, jnp.asarray(np.stack([given, moved])),
                                      jnp.asarray(np.stack([cur, cur])), jnp.asarray(node_type),
                                      jnp.asarray(mask)))
        base, pert = nxt[:, clot].mean(axis=1)
        out.append(share(pert - base, along, speed))
    return np.asarray(out)


def _split_rest(step, given):
    """``(lead frames or None, the frames before t)`` of a step's ``x_prev`` as float32: the
    carries perturb the frames before t and never the clot's rest state or start frames."""
    given = np.asarray(given, np.float32)
    start = getattr(step, "start_speed", False)
    lead = lead_count(step.rest_edges, start)
    return (given[..., :lead, :, :] if lead else None,
            history_frames(step.history, step.rest_edges, given, start))


def _join_rest(rest, frames):
    """The ``x_prev`` of the frames before t (``[H, N, 3]`` or ``[N, 3]``) and lead frames."""
    return frames if rest is None else lead_with_rest(rest, frames)


def _arrays(positions, node_type, mask):
    """The trajectory as float32, the node types, the real-node mask (default: all) and the
    clot mask, as numpy arrays."""
    node_type = np.asarray(node_type)
    mask = np.ones(len(node_type), bool) if mask is None else np.asarray(mask, bool)
    return (np.asarray(positions, np.float32), node_type, mask,
            np.asarray(clot_mask(node_type, mask), bool))
