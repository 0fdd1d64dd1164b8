"""Full-resolution steps on the cell grid: sized on the host from the data, checked, re-allocated.

The dense radius search costs ``O(N^2)``; from a few thousand nodes on the cell grid
(:mod:`thrombojax.graph.grid`) is faster but has fixed buffers. Following jax-md's allocate /
update split, the buffers are sized here, outside ``jit``, and the compiled step only reports
whether they were too small::

    step = allocate_grid(make_step(model), frames, node_type)   # host: GridSpec from the data
    out = step(params, stats, x_prev, x_cur, node_type, mask)    # jit: graph on the grid
    out.overflow                                                 # a buffer was too small
    result, step = run_checked(run, step)                        # host: grow and re-run

:func:`allocate_grid` sizes the :class:`~thrombojax.graph.grid.GridSpec` of the model's radius
graph (its ``radius``, ``max_neighbors`` and self loops) with
:func:`thrombojax.graph.capacity.estimate_capacity` from example frames (the frames of the
simulation to be rolled out, or the training data) expressed in the step's frame, and keeps it
only where it pays (:data:`~thrombojax.graph.neighbors.AUTO_GRID_MIN_NODES`): below that the
step is returned without a grid and nothing changes. :func:`run_checked` runs a compiled
function of the step that returns its overflow flag (the rollout accumulates it over every step:
:mod:`thrombojax.simulator.rollout`), grows the grid (:func:`thrombojax.graph.capacity.grow`)
and re-runs on overflow, and raises :class:`~thrombojax.errors.CapacityOverflowError` naming
the capacities when the re-allocations are exhausted. Nothing is ever silently truncated.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.errors import CapacityOverflowError, ConfigError
from thrombojax.graph.capacity import estimate_capacity, grow
from thrombojax.graph.neighbors import AUTO_GRID_MIN_NODES, _grid_pays
from thrombojax.models.registry import FlaxSurrogate
from thrombojax.simulator.step import LearnedStep

__all__ = [
    "DEFAULT_MAX_REGROWS",
    "graph_settings",
    "model_frame_positions",
    "allocate_grid",
    "grow_step",
    "run_checked",
]

DEFAULT_MAX_REGROWS: int = 4
"""Re-allocations (each growing the grid by ``growth``) tried before an overflow is an error."""


def graph_settings(step: LearnedStep) -> tuple[float, int, bool] | None:
    """``(radius, max_neighbors, self loops)`` of the step's radius graph; None if it has none
    (the constant-velocity baseline, a custom surrogate)."""
    if not isinstance(step.model, FlaxSurrogate):
        return None
    cfg = step.model.config
    return float(cfg.radius), int(cfg.max_neighbors), bool(step.model.self_loops)


@functools.partial(jax.jit, static_argnums=0)
def _in_frame(step: LearnedStep, frames, node_type, mask):
    return jax.vmap(lambda x: step.frame_of(x, node_type, mask).points(x))(frames)


def model_frame_positions(step: LearnedStep, frames, node_type, mask=None) -> np.ndarray:
    """``[F, N, 3]`` float32: the frames as the model sees them (the step's frame).

    Args:
        step: the learned step. frames: ``[F, N, 3]`` or ``[N, 3]`` scaled positions.
        node_type: ``[N]`` NodeType values. mask: ``[N]`` real nodes (default all).
    """
    frames = np.asarray(frames, np.float32)
    frames = frames[None] if frames.ndim == 2 else frames
    if step.frame == "global":
        return frames
    mask = np.ones(frames.shape[1], bool) if mask is None else np.asarray(mask, bool)
    return np.asarray(_in_frame(step, jnp.asarray(frames), jnp.asarray(node_type, jnp.int32),
                                jnp.asarray(mask)))


def allocate_grid(
    step: LearnedStep,
    frames,
    node_type,
    mask=None,
    *,
    margin: float = 1.25,
    max_frames: int = 8,
) -> LearnedStep:
    """The step with a cell grid sized from example frames where the grid pays (host side).

    Args:
        step: the learned step (an existing grid is replaced).
        frames: ``[F, N, 3]`` or ``[N, 3]`` scaled positions the step will see (e.g. every frame
            of the simulation to roll out); at most ``max_frames`` evenly spaced ones (first
            and last included) are measured.
        node_type: ``[N]`` NodeType values (the vessel frame needs them).
        mask: ``[N]`` bool real nodes (default all).
        margin: safety factor of :func:`thrombojax.graph.capacity.estimate_capacity` (> 1).
        max_frames: frames measured at most (each costs one k-d tree query on the host).
    Returns:
        ``step.with_grid(spec)`` when the model has a radius graph, ``N >=
        AUTO_GRID_MIN_NODES`` and the grid examines at most half the candidates of the dense
        search; else ``step.with_grid(None)`` (the dense search, as without this call).
    """
    settings = graph_settings(step)
    frames = np.asarray(frames, np.float32)
    frames = frames[None] if frames.ndim == 2 else frames
    if frames.ndim != 3 or frames.shape[-1] != 3 or frames.shape[0] < 1:
        raise ConfigError(f"allocate_grid: frames must be [F, N, 3] or [N, 3], got "
                          f"{frames.shape}")
    n = frames.shape[1]
    if settings is None or n < AUTO_GRID_MIN_NODES:
        return step.with_grid(None)
    pick = np.unique(np.linspace(0, frames.shape[0] - 1, max(1, int(max_frames))).round())
    seen = model_frame_positions(step, frames[pick.astype(int)], node_type, mask)
    radius, k, loop = settings
    spec = estimate_capacity(seen, radius, k, mask=mask, loop=loop, margin=margin)
    return step.with_grid(spec if _grid_pays(spec, n) else None)


def grow_step(step: LearnedStep, growth: float = 2.0) -> LearnedStep:
    """The step with its grid enlarged after an overflow (:func:`thrombojax.graph.grow`)."""
    settings = graph_settings(step)
    if step.grid is None or settings is None:
        raise ConfigError(f"grow_step: the step of model '{step.name}' has no cell grid to grow")
    return step.with_grid(grow(step.grid, settings[0], growth))


def run_checked(
    run: Callable[[LearnedStep], tuple[Any, Any]],
    step: LearnedStep,
    *,
    max_regrows: int = DEFAULT_MAX_REGROWS,
    growth: float = 2.0,
    what: str = "rollout",
) -> tuple[Any, LearnedStep]:
    """Run ``run(step) -> (result, overflow)``; on overflow grow the grid and run again.

    Args:
        run: a (compiled) function of the step returning its result and an overflow flag
            (``[]`` bool, e.g. any step of a rollout overflowed).
        step: the learned step; without a grid ``run`` is called once and its flag not read
            (the dense search cannot overflow).
        max_regrows: re-allocations allowed (0: an overflow is an error at once).
        growth: capacity factor per re-allocation.
        what: what is run, for the error message.
    Returns:
        ``(result, step)``: the overflow-free result and the step (grid) that produced it.
    Raises:
        CapacityOverflowError: the grid still overflowed after ``max_regrows`` re-allocations;
            the message names the capacities of the last grid.
    """
    for attempt in range(int(max_regrows) + 1):
        result, overflow = run(step)
        if step.grid is None or not bool(overflow):
            return result, step
        if attempt < int(max_regrows):
            step = grow_step(step, growth)
    g = step.grid
    raise CapacityOverflowError(
        f"{what} of model '{step.name}': the cell grid of its radius graph overflowed after "
        f"{int(max_regrows)} re-allocation(s); last capacity {g.capacity} nodes per run of "
        f"3 cells (heavy_capacity {g.heavy_capacity} for {g.heavy_nodes} heavy nodes), "
        f"cell_size {g.cell_size:.4g}, grid_shape {g.grid_shape}. Allow more re-allocations "
        f"(max_regrows) or size the grid from frames closer to the rollout (allocate_grid)"
    )
