"""Shared types: node types, the clot-node mask and the small frozen pytrees every layer uses.

The lowest layer of the package (it imports nothing from thrombojax); see ``docs/architecture.md``.
"""

from __future__ import annotations

from enum import IntEnum

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

__all__ = [
    "NodeType",
    "NUM_NODE_TYPES",
    "clot_mask",
    "ModelInput",
    "TargetStats",
    "node_type_one_hot",
]


class NodeType(IntEnum):
    """Kind of a node. The vessel wall is rigid; only clot nodes move."""

    VESSEL = 0
    CLOT = 1


NUM_NODE_TYPES: int = len(NodeType)

def clot_mask(node_type, mask=None):
    """Real clot nodes, the only nodes that move, enter a loss or a metric.

    Args:
        node_type: ``[..., n_nodes]`` :class:`NodeType` values (numpy or jax).
        mask: optional ``[..., n_nodes]`` bool, True on real (not padded) nodes.
    Returns:
        ``[..., n_nodes]`` bool of the same array kind as the inputs.
    """
    clot = node_type == NodeType.CLOT
    return clot if mask is None else clot & mask


def node_type_one_hot(node_type: jax.Array) -> jax.Array:
    """One-hot encode node types: ``[n_nodes] -> [n_nodes, NUM_NODE_TYPES]`` float32."""
    return jax.nn.one_hot(node_type, NUM_NODE_TYPES, dtype=jnp.float32)


@struct.dataclass
class ModelInput:
    """What every model sees for one sample (one frame), in scaled [-1, 1] coordinates.

    Attributes:
        positions: ``[n_nodes, 3]`` current positions s_t.
        velocity: ``[n_nodes, 3]`` v_t = s_t - s_{t-1}.
        node_type: ``[n_nodes]`` int32 :class:`NodeType` values (padded nodes: VESSEL).
        mask: ``[n_nodes]`` bool, True for real nodes, False for padding.
        extra: ``[n_nodes, F]`` more per-node features appended to :attr:`node_features`
            (the learned step's wall features), or None.
        rest: ``[n_nodes, 3]`` the rest state (the simulation's first frame, in the frame of
            :attr:`positions`) whose clot-clot edge displacements a model with edge features
            reads beside the current ones (``make_step(..., rest_edges=True)``), or None.
    """

    positions: jax.Array
    velocity: jax.Array
    node_type: jax.Array
    mask: jax.Array
    extra: jax.Array | None = None
    rest: jax.Array | None = None

    @property
    def n_nodes(self) -> int:
        return self.positions.shape[-2]

    @property
    def node_features(self) -> jax.Array:
        """``[n_nodes, 3 + NUM_NODE_TYPES (+ F)]`` the per-node input of every model: the
        (normalised) velocity, the node-type one-hot and :attr:`extra` when set (positions
        enter only through the graph's relative displacements)."""
        parts = [self.velocity, node_type_one_hot(self.node_type)]
        if self.extra is not None:
            parts.append(self.extra)
        return jnp.concatenate(parts, axis=-1)

    @property
    def clot_mask(self) -> jax.Array:
        """``[n_nodes]`` bool: real clot nodes (the nodes a loss or metric may see)."""
        return clot_mask(self.node_type, self.mask)


@struct.dataclass
class TargetStats:
    """Normalisation statistics of the model's output and velocity input, from the training split.

    The model predicts ``(a - mean) / std`` per axis, with
    ``a = s_{t+1} - 2 s_t + s_{t-1}`` in scaled coordinates, and sees the velocity feature
    ``v_t / velocity_std`` (like DeepMind's input normalisers): raw per-frame velocities in
    [-1, 1] coordinates are ~1e-3, far too small for a network's first layer to resolve.

    Attributes:
        mean: ``[3]`` float32.
        std: ``[3]`` float32, strictly positive.
        velocity_std: ``[]`` float32, strictly positive: the RMS of one velocity component over
            the training clot nodes (one number, so rotations keep their meaning).
    """

    mean: jax.Array
    std: jax.Array
    velocity_std: jax.Array = 1.0

    def normalize(self, accel: jax.Array) -> jax.Array:
        return (accel - self.mean) / self.std

    def denormalize(self, out: jax.Array) -> jax.Array:
        return out * self.std + self.mean

    def to_dict(self) -> dict:
        return {
            "mean": np.asarray(self.mean).tolist(),
            "std": np.asarray(self.std).tolist(),
            "velocity_std": float(np.asarray(self.velocity_std)),
        }

    @classmethod
    def from_dict(cls, d: dict) -> TargetStats:
        return cls(
            mean=jnp.asarray(d["mean"], jnp.float32),
            std=jnp.asarray(d["std"], jnp.float32),
            velocity_std=jnp.asarray(d.get("velocity_std", 1.0), jnp.float32),
        )
