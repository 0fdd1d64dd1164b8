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

``shared``: the share of the noise's variance common to every clot node of a window (one
Gaussian vector per window, added to every clot node, mixed with the independent per-node part
so each node's noise keeps the std ``std``). Independent per-node noise is averaged away by
message passing, so it does not teach a model that a whole clot's recent motion can be wrong,
which is the error a rollout makes (measured: a history model that keeps a clot-wide
acceleration the true clot does not have, ``experiments/results/ladder/README.md``).

Wall noise (:func:`add_wall_noise`): the states a rollout leaves the vessel by are states the
data never shows (the true clot never crosses the wall; the Gaussian noise above is far smaller
than a rollout's drift). Clot nodes within ``std`` of the wall are, each with probability 1/2,
moved through it along the outward wall normal to a signed distance ``std |z|`` outside
(:func:`thrombojax.graph.wall_nodes.local_wall_plane`, from the frame alone), in every input
frame alike (the node has drifted out and moves with its true velocity, as in a rollout), and
the later frames keep ``1 - gamma`` of the move (default ``gamma = 1/2``): the model learns to
take a node that crossed the wall back toward it by half the crossing per step. Only nodes
outside the wall are corrupted, so a clean node inside never looks like a corrupted one (no
bias on clean inputs).

History noise (:func:`add_history_noise`, a step with ``history >= 2``): the whole clot is
shifted by one Gaussian vector in the frames before s_{t-1}; s_{t-1}, s_t and the target stay.
The current velocity is exact, the history's accelerations are not, and the target does not
follow them: the model learns not to carry a clot-wide acceleration over from its history. In a
rollout the history is the model's own output, and a step that carries half of the last
step's acceleration over (measured on the ladder's wall-noise models: 0.47-0.48) amplifies
every small bias into a steady speed-up of the clot.

Speed noise (:func:`add_speed_noise`): the clot's input motion is scaled by ``1 + e``,
``e ~ N(0, std^2)`` one number per window: every frame before s_t is moved to
``s_t - (1 + e) (s_t - s_k)``, so each input velocity (and the history's accelerations) reads
``1 + e`` times the truth while s_t and the target stay: the model is shown a clot that moves
too fast or too slow and the true next frame. Why: the true clot slides at a steady speed set by
its drive and friction, which no input shows but the motion itself, and a step trained on clean
windows keeps a speed error it is given (:func:`thrombojax.eval.drift.speed_carry`: 1.003-1.038
on the ladder's models), so a small bias drifts a rollout's speed step after step; the per-node
noise above is averaged away by message passing. What a model can learn from it is the speed
the training data holds given the inputs, so a clot faster or slower than any training clot
could be pulled toward the training speeds. Measured (one seed, 0.1): a tiny model learns the
pull-back (``tests/test_speed_noise.py``), the ladder's MeshGraphNet does not (carry 1.006),
yet its rollouts speed up about half as much, on BendVessel and on a longer vessel whose clot
is 40 % faster than any training clot
(``experiments/results/ladder_budget/bendvessel_speed/README.md``).
With ``steady = F > 0`` the noise is drawn only for windows whose true clot keeps its speed:
the clot centroid's speed from s_t to s_{t+1} within a fraction ``F`` of its speed from s_{t-1}
to s_t. Where the true clot speeds up or slows down by more (a start, an outlet), the window
keeps its true motion, so the model may learn to carry the speed it is shown there: how fast a
clot leaves a vessel depends on how fast it is already leaving, which the vessel alone does
not tell (``experiments/results/ladder_budget/bendvessel_exit/README.md``).

Direction noise (:func:`add_direction_noise`): the clot's input motion is turned by one random
rotation per window, angle vector ``w ~ N(0, std^2 I)`` (radians): every frame before s_t is
moved to ``s_t - R(w) (s_t - s_k)``, so the clot comes into s_t from a slightly wrong direction
(moving across the vessel) while s_t and the target stay: the model is shown a clot whose
recent motion points off its path and the true next frame, which follows the vessel. Why: a
rollout's clot first drifts sideways off the true track at the right speed, and the step then
speeds up a clot whose input motion is the rollout's own; the true clot placed on the rollout's
track with the true motion is not sped up
(``experiments/results/ladder_budget/bendvessel_speed/README.md``): the step answers to the
direction of its input motion, which no noise above perturbs clot-wide. Measured (the ladder's
MeshGraphNet, 25 epochs, ``experiments/results/ladder_budget/bendvessel_direction/``): a tiny
model learns the pull-back (``tests/test_direction_noise.py``), the ladder's barely (direction
carry 1.015 without, 0.993 with 0.1 rad); with speed noise 0.1 its seed-0 rollout is the best
model alone so far (0.29x constant velocity), seed 2 0.41x, its seed-1 rollout among the worst
(1.80x), and at 0.3 rad its training loss does not fall. Not a default.

Time scaling (:func:`time_scale_window`, an augmentation rather than a noise): the window's clot
motion is played ``k`` times as fast, ``k = F^u``, ``u ~ U(-1, 1)``: every velocity becomes
``k v_t + k^2 (v_j - v_t)`` (so the current velocity ``k v_t`` and every acceleration ``k^2``
times the truth, as a trajectory ``x(k tau)``), the positions their sum from s_t, which stays;
the targets move with it. A clot of a dataset recorded at another frame rate, or driven
faster, moves more or less per frame than any training clot; the per-frame speed of a dataset
whose whole run is resampled to a fixed frame count is set by the vessel's length (the ladder's
BendVessel clots slide 0.27-0.34 r per frame, a 5 r longer outlet makes that 0.43).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.graph.wall_nodes import local_wall_plane
from thrombojax.train.speedup import clot_speeds
from thrombojax.types import clot_mask

__all__ = ["add_training_noise", "add_wall_noise", "add_history_noise", "add_speed_noise",
           "add_direction_noise", "noise_off", "rotation_matrix", "time_scale_window"]


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
    shared: float = 0.0,
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
        shared: share of the noise variance common to all clot nodes of the window, in
            ``[0, 1]`` (0: independent per node, the draws of earlier versions; 1: the whole
            clot moves together).
    Returns:
        ``[W, n_nodes, 3]`` the noisy window (s_{t-1}, s_t + n, s_{t+1} + (1 - gamma) n, ...).
    """
    if std == 0.0:
        return frames
    if not 0.0 <= shared <= 1.0:
        raise ValueError(f"shared must be in [0, 1], got {shared!r}")
    moving = clot_mask(node_type, mask)[:, None]
    if walk and current > 1:
        steps = std / jnp.sqrt(current) * _normal(key, (current, *frames.shape[1:]),
                                                  frames.dtype, shared)
        walked = jnp.where(moving[None], jnp.cumsum(jnp.cumsum(steps, axis=0), axis=0), 0.0)
        frames = frames.at[1:current + 1].add(walked)
        return frames.at[current + 1:].add((1.0 - gamma) * walked[-1])
    noise = jnp.where(moving, std * _normal(key, frames.shape[1:], frames.dtype, shared), 0.0)
    return frames.at[current].add(noise).at[current + 1:].add((1.0 - gamma) * noise)


def _normal(key: jax.Array, shape: tuple, dtype, shared: float) -> jax.Array:
    """Unit Gaussian ``[..., n_nodes, 3]``; with ``shared > 0`` that share of the variance is one
    draw per leading index common to every node (``shared = 0``: the plain draw of ``key``)."""
    if shared == 0.0:
        return jax.random.normal(key, shape, dtype)
    k_node, k_common = jax.random.split(key)
    node = jax.random.normal(k_node, shape, dtype)
    common = jax.random.normal(k_common, (*shape[:-2], 1, shape[-1]), dtype)
    return jnp.sqrt(1.0 - shared) * node + jnp.sqrt(shared) * common


def add_wall_noise(
    key: jax.Array,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    std: float,
    current: int = 1,
    gamma: float = 0.5,
) -> jax.Array:
    """Move clot nodes near the wall through it in every input frame (module docstring).

    Args:
        key: PRNG key.
        frames: ``[W, n_nodes, 3]`` the window, scaled coordinates; ``frames[current]`` is s_t,
            the frames before it the step's inputs.
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
        std: scale of the crossing, scaled coordinates (0 returns ``frames`` unchanged). Clot
            nodes with a signed wall distance (in s_t) above ``-std`` are candidates; each chosen
            one (probability 1/2) lands at ``max(signed, 0) + std |z|`` outside, ``z ~ N(0, 1)``.
        current: index of s_t in the window (the step's ``history``).
        gamma: share of the move the model learns to remove in one step, in ``[0, 1]``: the
            frames after s_t move by ``(1 - gamma)`` of it.
    Returns:
        ``[W, n_nodes, 3]``: the input frames ``0 .. current`` moved alike, the later frames by
        ``(1 - gamma)`` of the move.
    """
    if noise_off(std, "wall noise"):
        return frames
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"wall noise gamma must be in [0, 1], got {gamma!r}")
    signed, normal = local_wall_plane(frames[current], node_type, mask)
    k_pick, k_size = jax.random.split(key)
    n = signed.shape[0]
    # without a wall the normal is zero and nothing moves
    chosen = clot_mask(node_type, mask) & (signed > -std) & jax.random.bernoulli(k_pick, 0.5, (n,))
    depth = std * jnp.abs(jax.random.normal(k_size, (n,), frames.dtype))
    move = jnp.where(chosen[:, None], (jnp.maximum(-signed, 0.0) + depth)[:, None] * normal, 0.0)
    return frames.at[:current + 1].add(move).at[current + 1:].add((1.0 - gamma) * move)


def noise_off(std: float, what: str) -> bool:
    """True for ``std == 0`` (the noise is off); a negative ``std`` raises ValueError naming it."""
    if std == 0.0:
        return True
    if not std > 0.0:
        raise ValueError(f"{what} std must be >= 0, got {std!r}")
    return False


def add_history_noise(
    key: jax.Array,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    std: float,
    current: int,
) -> jax.Array:
    """Shift the whole clot by one random vector in the frames before s_{t-1} (module docstring).

    s_{t-1}, s_t and the targets stay, so the current velocity is exact and only the history's
    accelerations change (``a_{t-1}`` by the shift, ``a_{t-2}`` by minus it, ...): the model
    learns not to carry a common acceleration over from the history by itself, which in a
    rollout, where the history is the model's own output, feeds a drift of the clot's speed.

    Args:
        key: PRNG key.
        frames: ``[W, n_nodes, 3]`` the window, scaled coordinates; ``frames[current]`` is s_t.
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
        std: standard deviation of the shift per axis, scaled coordinates (0 returns
            ``frames`` unchanged).
        current: index of s_t in the window (the step's ``history``, >= 2: with one previous
            frame there is no history acceleration to perturb).
    Returns:
        ``[W, n_nodes, 3]``: the clot nodes of frames ``0 .. current - 2`` moved by one common
        ``N(0, std^2 I)`` vector; every other frame and node as given.
    """
    if noise_off(std, "history noise"):
        return frames
    if current < 2:
        raise ValueError(f"history noise needs a history of at least 2 frames (the step's "
                         f"accelerations), got {current!r}")
    shift = std * jax.random.normal(key, (1, 3), frames.dtype)
    move = jnp.where(clot_mask(node_type, mask)[:, None], shift, 0.0)
    return frames.at[:current - 1].add(move)


def add_speed_noise(
    key: jax.Array,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    std: float,
    current: int,
    steady: float = 0.0,
) -> jax.Array:
    """Scale the clot's input motion by one random factor ``1 + e`` (module docstring).

    Args:
        key: PRNG key.
        frames: ``[W, n_nodes, 3]`` the window, scaled coordinates; ``frames[current]`` is s_t.
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
        std: standard deviation of ``e``, a fraction of the motion (dimensionless; 0 returns
            ``frames`` unchanged).
        current: index of s_t in the window (the step's ``history``, >= 1).
        steady: ``F >= 0``; when ``> 0``, the window is returned as given unless the true
            clot centroid's speed from s_t to s_{t+1} is within a fraction ``F`` of its speed
            from s_{t-1} to s_t (a clot at rest is not noised; the window must hold s_{t+1}).
    Returns:
        ``[W, n_nodes, 3]``: the clot nodes of frames ``0 .. current - 1`` at
        ``s_t - (1 + e) (s_t - s_k)``; s_t, the later frames and every other node as given.
    """
    if noise_off(std, "speed noise"):
        return frames
    e = std * jax.random.normal(key, (), frames.dtype)
    if not steady >= 0.0:
        raise ValueError(f"speed noise: the steady fraction must be >= 0, got {steady!r}")
    if steady > 0.0 and frames.shape[0] <= current + 1:
        raise ValueError(f"speed noise on steady windows needs s_t+1 in the window "
                         f"({frames.shape[0]} frames, s_t at index {current})")
    out = _remap_motion(frames, node_type, mask, current, "speed noise",
                        lambda motion: (1.0 + e) * motion)
    if steady > 0.0:  # the window as given, to the last bit, unless its clot keeps its speed
        out = jnp.where(_keeps_speed(frames, node_type, mask, current, steady), out, frames)
    return out


def _keeps_speed(frames, node_type, mask, current, fraction):
    """Whether the clot centroid's speed from s_t to s_{t+1} lies within ``fraction`` of its
    speed from s_{t-1} to s_t (False for a clot at rest)."""
    before, after = clot_speeds(frames, node_type, mask, current)
    return (before > 0) & (jnp.abs(after - before) <= fraction * before)


def _remap_motion(frames, node_type, mask, current, what, remap):
    """The clot nodes of frames ``0 .. current - 1`` moved to ``s_t - remap(s_t - s_k)``; s_t,
    the later frames and every other node as given (``current < 1`` raises ValueError)."""
    if current < 1:
        raise ValueError(f"{what} needs s_t at index >= 1 of the window, got {current!r}")
    now = frames[current]
    before = frames[:current]
    moved = now[None] - remap(now[None] - before)
    moving = clot_mask(node_type, mask)[None, :, None]
    return frames.at[:current].set(jnp.where(moving, moved, before))


def rotation_matrix(w: jax.Array) -> jax.Array:
    """``[3, 3]`` rotation by the angle ``|w|`` (radians) about the axis ``w / |w|`` (Rodrigues;
    the identity for ``w = 0``, with finite gradients there)."""
    theta2 = jnp.sum(w * w)
    small = theta2 < 1e-12
    theta = jnp.sqrt(jnp.where(small, 1.0, theta2))
    a = jnp.where(small, 1.0 - theta2 / 6.0, jnp.sin(theta) / theta)
    b = jnp.where(small, 0.5 - theta2 / 24.0, (1.0 - jnp.cos(theta)) / (theta * theta))
    k = jnp.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]], w.dtype)
    return jnp.eye(3, dtype=w.dtype) + a * k + b * (k @ k)


def add_direction_noise(
    key: jax.Array,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    std: float,
    current: int,
) -> jax.Array:
    """Turn the clot's input motion by one random rotation (module docstring).

    Args:
        key: PRNG key.
        frames: ``[W, n_nodes, 3]`` the window, scaled coordinates; ``frames[current]`` is s_t.
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
        std: standard deviation per axis of the rotation's angle vector, radians (0 returns
            ``frames`` unchanged).
        current: index of s_t in the window (the step's ``history``, >= 1).
    Returns:
        ``[W, n_nodes, 3]``: the clot nodes of frames ``0 .. current - 1`` at
        ``s_t - R (s_t - s_k)``, ``R`` the rotation by ``w ~ N(0, std^2 I)``; s_t, the later
        frames and every other node as given.
    """
    if noise_off(std, "direction noise"):
        return frames
    rot = rotation_matrix(std * jax.random.normal(key, (3,), frames.dtype))
    return _remap_motion(frames, node_type, mask, current, "direction noise",
                         lambda motion: motion @ rot.T)


def time_scale_window(
    key: jax.Array,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    factor: float,
    current: int,
) -> jax.Array:
    """Play the clot's motion in the window ``k = factor^u`` times as fast (module docstring).

    Args:
        key: PRNG key.
        frames: ``[W, n_nodes, 3]`` the window (inputs, s_t at ``current``, targets).
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
        factor: the largest speed-up (>= 1; 1 returns ``frames`` unchanged); ``k`` is
            log-uniform in ``[1 / factor, factor]``.
        current: index of s_t in the window (>= 1).
    Returns:
        ``[W, n_nodes, 3]``: clot nodes with velocities ``k v_t + k^2 (v_j - v_t)`` summed from
        s_t (unchanged); every other node as given.
    """
    if factor == 1.0:
        return frames
    if not factor > 1.0:
        raise ValueError(f"time scale factor must be >= 1, got {factor!r}")
    if current < 1:
        raise ValueError(f"time scaling needs s_t at index >= 1 of the window, got {current!r}")
    k = jnp.exp(jnp.log(factor) * jax.random.uniform(key, (), frames.dtype, -1.0, 1.0))
    v = frames[1:] - frames[:-1]  # v[j - 1] = s_j - s_{j-1}
    now = v[current - 1]
    scaled = k * now[None] + k * k * (v - now[None])
    path = jnp.concatenate([jnp.zeros_like(frames[:1]), jnp.cumsum(scaled, axis=0)])
    out = frames[current][None] + path - path[current][None]
    return jnp.where(clot_mask(node_type, mask)[None, :, None], out, frames)
