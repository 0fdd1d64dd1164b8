"""The wall term of the training loss: predicted clot nodes further through the wall than the truth.

The rigid vessel holds the clot: in every frame of the data the clot lies inside the wall (up to
the solver's contact penetration). A rollout leaves it anyway, one small outward error after
another, and the containment guard of the rollout (:mod:`thrombojax.simulator.guards`) puts the
nodes back after the fact. This term makes the model itself pay for an outward error more than
for an inward one: for every predicted step ``j`` and clot node ``i``

    excess_ij = max(0, d(s^_{t+j}, i) - max(d(s_{t+j}, i), 0)) / sigma

where ``d(x, i)`` is node ``i``'s signed distance to the wall in frame ``x`` (positive outside,
:func:`thrombojax.graph.wall_nodes.local_wall_plane`: the wall from the frame's own vessel nodes,
no triangles needed), ``s^`` the prediction, ``s`` the true frame and ``sigma`` the RMS over x, y,
z of the target acceleration's standard deviation (:class:`thrombojax.types.TargetStats`), so the
excess is in the same units as the loss's normalised error. The term is zero on the truth and on
every prediction inside the wall, whatever its error there; a node the truth has through the
wall (penetration) is charged only for going further.

Its gradient is the wall's outward normal at the node (the wall planes are held fixed, as the
guard's are), so it pushes a prediction that crossed the wall back along the normal and nowhere
else. ``wall_sum`` pools like the loss's other terms: summed over the clot nodes, averaged over the
``k`` steps; :func:`thrombojax.train.step.batch_loss` adds ``wall_loss_weight`` times its mean
over the batch's clot nodes (``thrombojax train --wall-loss-weight W``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.graph.wall_nodes import local_wall_plane
from thrombojax.types import TargetStats, clot_mask

__all__ = ["wall_excess", "wall_sum"]


def wall_excess(
    predicted: jax.Array,
    truth: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    stats: TargetStats,
) -> jax.Array:
    """``[N]``: how much further each clot node of ``predicted`` is through the wall than in
    ``truth``, in units of the normalised acceleration (module docstring); 0 on other nodes.

    Args:
        predicted: ``[N, 3]`` the predicted frame (scaled coordinates); gradients flow to it
            along the wall's normal. truth: ``[N, 3]`` the true frame (no gradient).
        node_type: ``[N]`` NodeType. mask: ``[N]`` real nodes. stats: the target statistics.
    """
    signed, normal = local_wall_plane(predicted, node_type, mask)
    true_signed, _ = local_wall_plane(truth, node_type, mask)
    # the signed distance with the wall planes held fixed: its gradient is the normal
    moved = predicted - jax.lax.stop_gradient(predicted)
    outward = signed + jnp.sum(moved * normal, axis=-1) - jnp.maximum(true_signed, 0.0)
    sigma = jnp.sqrt(jnp.mean(jnp.square(jnp.asarray(stats.std, predicted.dtype))))
    return jnp.where(clot_mask(node_type, mask), jax.nn.relu(outward), 0.0) / sigma


def wall_sum(
    positions: jax.Array,
    truth: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    stats: TargetStats,
) -> jax.Array:
    """The squared excess summed over the clot nodes and averaged over the ``k`` steps.

    Args:
        positions: ``[k, N, 3]`` predicted frames. truth: ``[k, N, 3]`` the true ones.
        node_type, mask, stats: as :func:`wall_excess`.
    Returns:
        ``[]`` float.
    """
    # a loop over the (static, small) k, as for the step's prior in the loss: the wall
    # planes' eigendecompositions are not vmapped over steps (thrombojax.train.loss)
    per_step = [jnp.sum(jnp.square(wall_excess(positions[j], truth[j], node_type, mask, stats)))
                for j in range(positions.shape[0])]
    return jnp.mean(jnp.stack(per_step))
