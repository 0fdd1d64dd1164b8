"""The learned step's option checks and its prior (:class:`thrombojax.simulator.step.LearnedStep`
calls them; kept here so the step's module stays one responsibility).

The prior: ``make_step(model, prior_radius=w)`` adds the vessel-following prior to constant
velocity, every clot node's velocity turned onto the vessel's axis at its speed
(:func:`thrombojax.graph.vessel_axis.follow_axis_offset`), and the model learns the rest;
``centre_pull=K, centre_unit=r`` also tilts those velocities toward the middle of the vessel's
cross-section, by ``K`` of the clot centroid's offset from it each step (beyond
``centre_tolerance``), at the same speed (:func:`thrombojax.graph.section.centre_pull`): the
prior alone has no pull back to the middle and carries a clot off it in a bend
(``experiments/results/ladder_budget/bendvessel_pull/README.md``).
"""

from __future__ import annotations

from typing import Any

import jax

from thrombojax.errors import ConfigError
from thrombojax.graph.frame import FRAMES
from thrombojax.graph.section import centre_pull
from thrombojax.graph.vessel_axis import follow_axis_offset, vessel_axis

__all__ = ["LENGTHS", "check_step_options", "step_prior"]

LENGTHS: tuple[str, ...] = ("wall_cutoff", "axis_radius", "prior_radius", "lateral_radius",
                            "outlet_radius", "shape_radius", "clearance_radius",
                            "section_radius", "centre_pull", "centre_unit", "centre_tolerance")
"""The step's fields that must be finite numbers >= 0."""


def check_step_options(step: Any) -> None:
    """Raise :class:`ConfigError` naming the field for a step whose options do not fit."""
    if step.frame not in FRAMES:
        raise ConfigError(f"learned step: frame must be one of {list(FRAMES)}, "
                          f"got {step.frame!r}")
    for name in LENGTHS:
        if not (getattr(step, name) >= 0 and getattr(step, name) < float("inf")):
            raise ConfigError(f"learned step: {name} must be a finite number >= 0, "
                              f"got {getattr(step, name)!r}")
    if step.centre_pull > 0 and not (step.centre_pull <= 1 and step.prior_radius > 0
                                     and step.centre_unit > 0):
        raise ConfigError(f"learned step: centre_pull {step.centre_pull!r} needs to be <= 1, "
                          "with the vessel-following prior (prior_radius > 0) and a vessel "
                          "radius (centre_unit > 0)")
    if step.wall_clot_mean and not step.wall_cutoff > 0:
        raise ConfigError("learned step: wall_clot_mean needs wall features (wall_cutoff > 0)")
    if not isinstance(step.history, int) or isinstance(step.history, bool) or step.history < 1:
        raise ConfigError(f"learned step: history must be an int >= 1 (frames before t), "
                          f"got {step.history!r}")
    if not isinstance(step.start_speed, int) or step.start_speed < 0:
        raise ConfigError(f"learned step: start_speed must be an int >= 0 (frames the start "
                          f"speed spans; 0: off), got {step.start_speed!r}")
    if step.rest_edges and not getattr(step.model, "rest_edges", False):
        raise ConfigError(f"learned step: model '{step.model.name}' has no edge features "
                          f"to give rest-state displacements to (rest_edges: meshgraphnet)")


def step_prior(step: Any, x_last, x_cur, node_type, mask, context=None,
               axis: jax.Array | None = None) -> jax.Array | float:
    """What ``step`` adds to constant velocity before the model's acceleration (the module
    docstring): 0 without a prior. ``x_last`` is s_{t-1}; ``context``: a rollout's
    :class:`~thrombojax.simulator.context.StepContext` (its wall search); ``axis``: the vessel
    axis of ``x_cur`` at ``prior_radius`` if computed before."""
    if step.prior_radius <= 0:
        return 0.0
    if axis is None:
        axis = vessel_axis(x_cur, node_type, mask, radius=step.prior_radius,
                           patch=None if context is None else context.global_patch)
    pull = None if step.centre_pull <= 0 else centre_pull(
        x_cur, node_type, mask, unit=step.centre_unit, strength=step.centre_pull,
        tolerance=step.centre_tolerance, axis=axis)
    return follow_axis_offset(x_last, x_cur, node_type, mask, radius=step.prior_radius,
                              axis=axis, pull=pull)
