"""The extra node features of a learned step's input, after the velocity and node type.

:meth:`thrombojax.simulator.step.LearnedStep._inputs` (and the flat batch step through it)
appends, in this order and each only when the step has it:

1. the history: the ``H - 1`` accelerations before t (``history >= 2``;
   :func:`thrombojax.simulator.kinematics.past_accelerations`), divided by the RMS of the
   target statistics' ``std``;
2. the wall features (``wall_cutoff > 0``): distance and direction to the nearest vessel node,
   or the signed wall distance and outward normal (``wall_signed``), and their clot-wide mean
   distance (``wall_clot_mean``) (:mod:`thrombojax.graph.wall_nodes`);
3. the velocity split along and across the local vessel axis (``axis_radius > 0``;
   :func:`thrombojax.graph.vessel_axis.axis_velocity_features`);
4. where the clot is against the vessel's open ends, ahead of its motion, per node and
   clot-wide (``outlet_radius > 0``; :func:`thrombojax.graph.vessel_axis.outlet_features`);
5. each clot node's place along the clot's motion and the clot's length and width
   (``shape_radius > 0``; :func:`thrombojax.graph.clot_shape.clot_shape_features`);
6. the distance from the clot's centroid to the nearest vessel node, on every clot node
   (``clearance_radius > 0``; :func:`thrombojax.graph.clearance.clot_clearance`);
7. the width of the vessel's cross-section at the clot's centroid, on every clot node
   (``section_radius > 0``; :func:`thrombojax.graph.section.clot_section_features`);
8. the clot's start speed, its speed in the true frames its rollout starts from, on every clot node
   (``start_speed``; :func:`thrombojax.simulator.start_speed.start_speed_feature`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.graph.clearance import clot_clearance
from thrombojax.graph.clot_shape import clot_shape_features
from thrombojax.graph.section import clot_section_features
from thrombojax.graph.vessel_axis import axis_velocity_features, outlet_features
from thrombojax.graph.wall_nodes import clot_wall_mean, signed_wall_features, wall_node_features
from thrombojax.simulator.kinematics import past_accelerations
from thrombojax.simulator.previous import history_frames, start_frames
from thrombojax.simulator.start_speed import start_speed_feature

__all__ = ["extra_features"]


def extra_features(step, stats, x_prev, x_cur, node_type, mask, velocity_scale, axes):
    """``[N, F]`` the extra features of ``step`` (a
    :class:`~thrombojax.simulator.step.LearnedStep`) at frame t, or None when it has none.

    ``x_prev`` is the step's ``x_prev`` (``[H, N, 3]`` with history, led by the rest frame
    with ``rest_edges`` and the start frames with ``start_speed``), ``x_cur`` s_t, both in
    the coordinates of the model's inputs; ``stats`` None (initialisation) gives unit scales;
    ``axes`` is :func:`~thrombojax.simulator.context.shared_axes` of ``x_cur``.
    """
    last = step.last_previous(x_prev)
    extra = []
    if step.history > 1:
        feats = past_accelerations(history_frames(step.history, step.rest_edges, x_prev,
                                                  step.start_speed), x_cur,
                                   mask, 1.0 if stats is None else
                                   jnp.sqrt(jnp.mean(stats.std ** 2)))
        extra.append(jax.lax.stop_gradient(feats) if step.stop_history_gradient else feats)
    if step.wall_cutoff > 0:
        features = signed_wall_features if step.wall_signed else wall_node_features
        extra.append(features(x_cur, node_type, mask, cutoff=step.wall_cutoff))
        if step.wall_clot_mean:
            extra.append(clot_wall_mean(extra[-1], node_type, mask))
    if step.axis_radius > 0:
        extra.append(axis_velocity_features(
            last, x_cur, node_type, mask, radius=step.axis_radius,
            velocity_scale=velocity_scale, axis=axes(step.axis_radius)))
    if step.outlet_radius > 0:
        extra.append(outlet_features(last, x_cur, node_type, mask, radius=step.outlet_radius))
    if step.shape_radius > 0:
        extra.append(clot_shape_features(last, x_cur, node_type, mask, scale=step.shape_radius))
    if step.clearance_radius > 0:
        extra.append(clot_clearance(x_cur, node_type, mask, scale=step.clearance_radius))
    if step.section_radius > 0:
        extra.append(clot_section_features(x_cur, node_type, mask, scale=step.section_radius))
    if step.start_speed:
        extra.append(start_speed_feature(start_frames(step.rest_edges, x_prev), node_type, mask,
                                         velocity_scale * step.start_speed))  # over K frames
    return jnp.concatenate(extra, axis=-1) if extra else None
