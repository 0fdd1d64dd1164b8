"""Training on guarded states: the rollout's guards applied to the pushed steps or the inputs.

A guarded rollout (:mod:`thrombojax.simulator.guard_set`) does not feed the learned step its own
predictions: coherence pulls the clot toward a rigid copy of its first frame and containment puts
nodes that crossed the wall back inside, and the next step reads the corrected positions (and the
velocity they imply). A model trained only on true frames (or, with push-forward, on its own
unguarded predictions) never saw such a state: measured on BendVessel each guard makes the
held-out clot lag where it leaves the vessel by about 0.2 vessel radii, and the two add up
(``experiments/results/ladder_budget/guards_exit/``).

With ``pushforward_guards`` the push-forward steps of the loss (:mod:`thrombojax.train.loss`; no
gradients through them) pass every predicted frame through the same two guards before the next
step reads it, so the loss steps start from the state a guarded rollout would be in, and their
target is still the true frame: the model learns to correct what the guards did to the clot's
position and velocity. The guards here are the rollout's, computed from the training window:

* coherence: :func:`thrombojax.simulator.guards.coherence` at full stiffness toward a rigid copy
  of the clot in the simulation's first frame (the window is led by it, as for ``rest_edges``),
  with the tolerance ``tolerance`` (scaled coordinates);
* containment: every clot node further out through the wall than ``margin`` is moved back along
  the wall's normal, the wall given by the frame's own vessel nodes
  (:func:`thrombojax.graph.wall_nodes.local_wall_plane`, as the loss's wall term; the rollout
  uses the wall triangles when the dataset has them). A node the true frame has further out
  (the clot past the vessel's open end, which local planes do not detect, or the solver's
  contact penetration) is left as far out as the truth: containment in the rollout frees nodes
  past the open end too.

Both are applied in the rollout's order (coherence, then containment), on clot rows only; the
vessel is rigid and never moved.

With ``input_guards`` (no push-forward pass) the same guards act on the window's input frames
s_{t-H} ... s_t after the training noise (:func:`guard_inputs`), each measured against its own
clean frame, and the target stays the true s_{t+1}: on the truth containment does nothing, so
this is coherence where the true clot deforms beyond the tolerance (BendVessel's exit) and
containment of what the noise pushed through the wall.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from thrombojax.graph.wall_nodes import local_wall_plane
from thrombojax.simulator.guards import coherence
from thrombojax.types import clot_mask

__all__ = ["PushGuards", "guard_frame", "guarded_push", "guard_inputs"]

MARGIN_R: float = 0.01
"""Containment's margin in vessel radii: the rollout's default (about the solver's contact
penetration)."""


@struct.dataclass
class PushGuards:
    """The guards of the push-forward steps, in scaled coordinates (static under ``jit``).

    Attributes:
        margin: how far (>= 0) a clot node may lie outside the wall before it is put back.
        tolerance: coherence's tolerance (>= 0): how far a node may lie from the rigid copy of
            the clot's first frame before it is pulled toward it.
    """

    margin: float = struct.field(pytree_node=False)
    tolerance: float = struct.field(pytree_node=False)

    def __post_init__(self):
        if not (self.margin >= 0 and self.tolerance >= 0):
            raise ValueError(f"push-forward guards: margin and tolerance must be >= 0, got "
                             f"{self.margin}, {self.tolerance}")


def guard_frame(x: jax.Array, truth: jax.Array, rest: jax.Array, node_type: jax.Array,
                mask: jax.Array, guards: PushGuards) -> jax.Array:
    """``[N, 3]``: a predicted frame after coherence and containment (module docstring).

    Args:
        x: ``[N, 3]`` the predicted frame (scaled coordinates; no gradient is meant to flow).
        truth: ``[N, 3]`` the true frame at the same time (how far out its clot nodes lie).
        rest: ``[N, 3]`` the simulation's first frame (the clot's reference shape).
        node_type: ``[N]`` NodeType. mask: ``[N]`` real nodes. guards: the settings.
    """
    clot = clot_mask(node_type, mask)
    x, _ = coherence(x, rest, clot, stiffness=1.0, tolerance=guards.tolerance)
    signed, normal = local_wall_plane(x, node_type, mask)
    true_signed, _ = local_wall_plane(truth, node_type, mask)
    excess = jax.nn.relu(signed - jnp.maximum(true_signed, guards.margin))
    return x - jnp.where(clot, excess, 0.0)[:, None] * normal


def guarded_push(step, params: dict, stats, frames: jax.Array, rest: jax.Array,
                 node_type: jax.Array, mask: jax.Array, n_steps: int, guards: PushGuards, *,
                 train: bool, rng: jax.Array | None) -> jax.Array:
    """``[n_steps, N, 3]``: the learned step applied ``n_steps`` times from the window's frame
    ``H`` (``H`` the step's history), each prediction guarded before the next step reads it.

    Args:
        step: the learned step (:class:`thrombojax.simulator.step.LearnedStep`).
        params, stats: its variables and target statistics.
        frames: ``[W, N, 3]`` the window (s_{t-H}, ..., s_t, s_{t+1}, ...), ``W >= H + 1 +
            n_steps``: frame ``H + j`` is the truth the ``j``-th pushed frame is measured against.
        rest: ``[N, 3]`` the simulation's first frame. node_type, mask: as :func:`guard_frame`.
        n_steps: the push-forward steps (static, >= 1). guards: the settings.
        train, rng: the model's training mode and dropout key (folded with the step index).
    Returns:
        The guarded frames s^_{t+1} ... s^_{t+n_steps}, gradients stopped.
    """
    h = step.history
    seq = frames[:h + 1]
    for j in range(n_steps):  # static and small: the steps of the push-forward
        key = None if rng is None else jax.random.fold_in(rng, j)
        out = step(params, stats, step.previous(seq, seq.shape[0] - 1, rest), seq[-1],
                   node_type, mask, train=train, rng=key)
        nxt = guard_frame(out.positions, frames[h + 1 + j], rest, node_type, mask, guards)
        seq = jnp.concatenate([seq, nxt[None]])
    return jax.lax.stop_gradient(seq[h + 1:])


def guard_inputs(frames: jax.Array, clean: jax.Array, rest: jax.Array, node_type: jax.Array,
                 mask: jax.Array, guards: PushGuards, history: int) -> jax.Array:
    """``[W, N, 3]``: the window with its ``history + 1`` input frames guarded (``input_guards``).

    Args:
        frames: ``[W, N, 3]`` the (noisy) training window, s_{t-H} ... s_t first.
        clean: ``[W, N, 3]`` the same window before the noise: how far out each true node lies.
        rest: ``[N, 3]`` the simulation's first frame. node_type, mask, guards: as
            :func:`guard_frame`. history: ``H`` (static).
    Returns:
        The window, frames ``0 .. H`` guarded and the later ones (the targets) as they were.
    """
    inputs = [guard_frame(frames[j], clean[j], rest, node_type, mask, guards)
              for j in range(history + 1)]
    return jnp.concatenate([jnp.stack(inputs), frames[history + 1:]])
