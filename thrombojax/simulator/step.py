"""The one learned step: inputs -> graph -> model -> denormalise -> integrate.

Every consumer (the single-step and k-step training losses, the ``lax.scan`` rollout, evaluation,
the speed benchmark) calls the :class:`LearnedStep` made by :func:`make_step`; nothing else in the
package writes this sequence. In the manner of jax-md's ``simulate`` factories the factory fixes
the static part (the surrogate) and returns pure functions of arrays::

    step = make_step(model)
    params = step.init(rng, x_prev, x_cur, node_type, mask)
    out = step(params, stats, x_prev, x_cur, node_type, mask)     # StepOutput
    out.positions                                                  # s_{t+1}

The step, in scaled [-1, 1] coordinates::

    inputs  = (s_t, v_t / velocity_std, node type, mask),  v_t = s_t - s_{t-1}
    out     = model(inputs, graph built from s_t)          # normalised acceleration
    a_t     = out * std + mean                             # TargetStats of the training split
    s_{t+1} = s_t + v_t + a_t  for real clot nodes;  s_t for vessel and padded nodes (rigid)

:class:`LearnedStep` is a frozen, hashable dataclass, so it is a static argument of ``jax.jit``
(one compilation per surrogate and shapes).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
from flax import struct

from thrombojax.models.registry import Surrogate
from thrombojax.types import ModelInput, TargetStats, clot_mask

__all__ = [
    "StepOutput",
    "LearnedStep",
    "make_step",
    "make_input",
    "target_acceleration",
    "integrate",
]


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


@struct.dataclass
class StepOutput:
    """What one learned step returns.

    Attributes:
        positions: ``[n_nodes, 3]`` s_{t+1} (vessel and padded nodes equal s_t exactly).
        output: ``[n_nodes, 3]`` the raw model output (normalised acceleration), what the
            training loss compares with the normalised target.
    """

    positions: jax.Array
    output: jax.Array


@dataclasses.dataclass(frozen=True)
class LearnedStep:
    """The learned simulator of one surrogate: pure functions of (params, stats, frames).

    Build it with :func:`make_step`. Hashable (the surrogate is a frozen dataclass), so it can
    be a static argument of ``jax.jit``.

    Attributes:
        model: the surrogate (:func:`thrombojax.models.create_model`).
    """

    model: Surrogate

    @property
    def name(self) -> str:
        """The surrogate's registry name."""
        return self.model.name

    def inputs(
        self, stats: TargetStats, x_prev: jax.Array, x_cur: jax.Array, node_type: jax.Array,
        mask: jax.Array,
    ) -> ModelInput:
        """The model input of frame t (velocity normalised by ``stats.velocity_std``)."""
        return make_input(x_prev, x_cur, node_type, mask, stats.velocity_std)

    def __call__(
        self,
        params: dict,
        stats: TargetStats,
        x_prev: jax.Array,
        x_cur: jax.Array,
        node_type: jax.Array,
        mask: jax.Array,
        *,
        train: bool = False,
        rng: jax.Array | None = None,
    ) -> StepOutput:
        """One step s_{t-1}, s_t -> s_{t+1} (see the module docstring).

        Args:
            params: the surrogate's variables. stats: normalisation statistics.
            x_prev, x_cur: ``[n_nodes, 3]`` scaled positions s_{t-1}, s_t.
            node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
            train: training mode (dropout). rng: PRNG key of the dropout stream.
        Returns:
            The :class:`StepOutput`.
        """
        inputs = self.inputs(stats, x_prev, x_cur, node_type, mask)
        graph = self.model.build_graph(inputs)
        out = self.model.apply(params, inputs, graph, train=train, rng=rng)
        x_next = integrate(x_prev, x_cur, stats.denormalize(out), node_type, mask)
        return StepOutput(positions=x_next, output=out)

    def init(
        self, rng: jax.Array, x_prev: jax.Array, x_cur: jax.Array, node_type: jax.Array,
        mask: jax.Array,
    ) -> dict:
        """Initialise the surrogate's variables on one frame (compiled once per shape)."""
        return _init(self, rng, jnp.asarray(x_prev, jnp.float32), jnp.asarray(x_cur, jnp.float32),
                     jnp.asarray(node_type, jnp.int32), jnp.asarray(mask, bool))


@functools.partial(jax.jit, static_argnums=0)
def _init(step: LearnedStep, rng, x_prev, x_cur, node_type, mask) -> dict:
    inputs = make_input(x_prev, x_cur, node_type, mask)
    return step.model.init(rng, inputs, step.model.build_graph(inputs))


def make_step(model: Surrogate) -> LearnedStep:
    """The learned simulator of a surrogate (see the module docstring)."""
    return LearnedStep(model=model)
