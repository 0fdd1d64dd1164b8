"""A frame fixed to the rigid vessel: inputs that do not depend on the global orientation.

The vessel of every dataset is rigid, so its nodes define a frame that moves with the vessel:
origin at the vessel nodes' centroid, axes the principal axes of their covariance (largest
variance first), each axis signed so that the third moment of the vessel nodes along it is
positive (the bend of a vessel is asymmetric), the third axis ``e1 x e2`` so that the frame is a
rotation (det +1). A global rotation ``R`` and translation ``t`` of a simulation move the frame
with it (``origin -> R origin + t``, ``axes -> R axes``), so coordinates expressed in it
(:meth:`VesselFrame.points`, :meth:`VesselFrame.vectors`) are the same for every orientation:
a model that sees only them is invariant to the vessel's orientation up to rounding, whatever
rotations it was trained on. (Inputs that search the wall for the nearest vessel nodes rank
equal distances by node index, :func:`thrombojax.graph.wall_nodes.tie_key`, so that rounding
in turned coordinates does not pick other nodes.)

Limits (documented in ``docs/rollouts.md``): an axis whose third moment is zero (a vessel
symmetric about the plane normal to it) has no preferred sign; only the third axis may be such
an axis in practice (``e1 x e2`` fixes it), and a mirror-symmetric vessel's physics is
symmetric too. Two equal principal variances (a straight tube) leave the rotation about the
tube's axis undetermined: the frame is still constant over a rollout (the vessel does not
move), but two orientations of the same tube may get different frames.

The frame is computed under ``jit`` from one frame's positions (vessel nodes never move, so
every frame of a simulation gives the same frame) with gradients stopped.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from thrombojax.types import NodeType

__all__ = ["VesselFrame", "vessel_frame", "FRAMES"]

FRAMES: tuple[str, ...] = ("global", "vessel")
"""Frames a learned step can work in: the dataset's own axes, or :func:`vessel_frame`."""


@struct.dataclass
class VesselFrame:
    """An origin and three orthonormal axes (the columns of ``axes``), ``det(axes) = +1``.

    Attributes:
        origin: ``[3]`` the vessel nodes' centroid.
        axes: ``[3, 3]`` rotation whose columns are the frame's axes in global coordinates.
    """

    origin: jax.Array
    axes: jax.Array

    def points(self, x: jax.Array) -> jax.Array:
        """Global positions ``[..., 3]`` -> frame coordinates ``(x - origin) @ axes``."""
        return (x - self.origin) @ self.axes

    def vectors(self, v: jax.Array) -> jax.Array:
        """Global vectors ``[..., 3]`` (velocities, accelerations) -> frame components."""
        return v @ self.axes

    def vectors_to_global(self, v: jax.Array) -> jax.Array:
        """Frame components ``[..., 3]`` -> global vectors (the inverse of :meth:`vectors`)."""
        return v @ self.axes.T


def vessel_frame(
    x: jax.Array, node_type: jax.Array, mask: jax.Array | None = None
) -> VesselFrame:
    """The frame of the rigid vessel nodes of one frame (see the module docstring). Jittable.

    Args:
        x: ``[n_nodes, 3]`` positions of one frame.
        node_type: ``[n_nodes]`` NodeType values; vessel nodes define the frame.
        mask: ``[n_nodes]`` bool real-node mask (padded nodes are ignored); None: all real.
    Returns:
        The :class:`VesselFrame`. With fewer than 3 vessel nodes, the identity frame at the
        centroid of the real nodes (nothing to orient by).
    """
    x = jax.lax.stop_gradient(jnp.asarray(x, jnp.float32))
    node_type = jnp.asarray(node_type)
    real = jnp.ones(node_type.shape, bool) if mask is None else jnp.asarray(mask, bool)
    vessel = real & (node_type == NodeType.VESSEL)
    n_vessel = jnp.sum(vessel)
    use = jnp.where(n_vessel >= 3, vessel, real)
    w = use.astype(jnp.float32)[:, None]
    n = jnp.maximum(jnp.sum(w), 1.0)
    origin = jnp.sum(w * x, axis=0) / n
    d = (x - origin) * w
    cov = d.T @ d / n
    _, vecs = jnp.linalg.eigh(cov)
    e = vecs[:, ::-1]  # largest variance first
    third = jnp.sum(w * (d @ e) ** 3, axis=0)
    e = e * jnp.where(third < 0.0, -1.0, 1.0)[None, :]
    e3 = jnp.cross(e[:, 0], e[:, 1])
    axes = jnp.stack([e[:, 0], e[:, 1], e3], axis=1)
    axes = jnp.where(n_vessel >= 3, axes, jnp.eye(3, dtype=x.dtype))
    return VesselFrame(origin=origin, axes=axes)
