"""The coherence guard's tolerance from data: how far true clots stray from a rigid copy.

:func:`clot_deviations` measures, for every frame of a simulation from the rollout's start on,
how far each true clot node lies from its place in the best rigid copy of the clot at the start
frame (the coherence guard's own measure, :func:`thrombojax.simulator.guards.coherence` with
tolerance 0), in vessel radii. :func:`fit_coherence` pools those distances over a set of
simulations (a run's training simulations) and returns their ``quantile`` as the tolerance, so
that the guard would leave the true clots of those simulations alone at all but ``1 -
quantile`` of their (node, frame) pairs. ``thrombojax rollout --coherence-tolerance auto`` uses
it with the run's training simulations: a dataset whose clots deform much gets a wide
tolerance, a nearly rigid one a tight tolerance.

Measured on the built-in datasets (``experiments/results/ladder_budget/coherence_auto/
fit_table.md``): the true clots stray at most 0.38-0.50 r on BendVessel and 0.61-1.30 r on
ClotEntry; the 95th percentile over the training simulations, the tolerance ``auto`` gives, is
0.21 r on BendVessel and 0.38 r on ClotEntry. A rollout at 1 r lets its clot grow by a third on
BendVessel; at ``auto`` it stays within 7 % of the true clot's size and ends nearer the truth
(``experiments/results/ladder_budget/coherence_auto/README.md``).
"""

from __future__ import annotations

import functools
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.errors import DatasetError
from thrombojax.eval.centring_fit import check_fit_request
from thrombojax.simulator.guards import coherence
from thrombojax.types import NodeType

__all__ = ["AUTO_QUANTILE", "clot_deviations", "fit_coherence"]

AUTO_QUANTILE: float = 0.95
"""The share of the true clots' (node, frame) pairs that ``--coherence-tolerance auto`` leaves
alone."""


@functools.partial(jax.jit, static_argnames="stretching")
def _frame_deviations(frames: jax.Array, ref: jax.Array, max_stretch: jax.Array,
                      stretching: bool) -> jax.Array:
    """``[F, C]``: each clot node's distance from its place in the best rigid (or, when
    ``stretching``, bounded-stretch) copy of ``ref``."""
    mask = jnp.ones(ref.shape[0], bool)
    ms = max_stretch if stretching else None
    return jax.vmap(lambda x: coherence(x, ref, mask, stiffness=1.0, tolerance=0.0,
                                        max_stretch=ms)[1])(frames)


def clot_deviations(positions: np.ndarray, node_type: np.ndarray, start: int,
                    radius: float, *, max_stretch: float | None = None) -> np.ndarray:
    """``[T - start - 1, C]``: every true clot node's distance (vessel radii) from its place in
    the best rigid copy of the clot at frame ``start``, at each frame after ``start``.

    Args:
        positions: ``[T, N, 3]`` a simulation's frames (any length unit).
        node_type: ``[N]`` node types (the clot's nodes are measured).
        start: the rollout's start frame (the coherence guard's reference), ``0 <= start < T``.
        radius: the vessel radius in the positions' unit (> 0).
        max_stretch: the coherence guard's ``max_stretch`` (None: its rigid copy).
    Raises:
        DatasetError: no clot node, or ``start`` outside the frames.
    """
    pos = np.asarray(positions, np.float32)
    clot = np.asarray(node_type) == NodeType.CLOT
    if not clot.any():
        raise DatasetError("clot_deviations: the simulation has no clot node")
    if not 0 <= start < pos.shape[0]:
        raise DatasetError(f"clot_deviations: start frame {start} is outside the simulation's "
                           f"{pos.shape[0]} frames")
    clot_pos = jnp.asarray(pos[:, clot])
    dev = _frame_deviations(clot_pos[start + 1:], clot_pos[start],
                            jnp.float32(max_stretch or 1.0), max_stretch is not None)
    return np.asarray(dev) / radius


def fit_coherence(dataset: Any, names: list[str] | tuple[str, ...], radius: float, start: int,
                  *, quantile: float = AUTO_QUANTILE,
                  max_stretch: float | None = None) -> dict[str, Any]:
    """The coherence tolerance (vessel radii) that leaves ``quantile`` of the true clots'
    (node, frame) pairs of the simulations ``names`` alone.

    Args:
        dataset: an open :class:`thrombojax.io.hdf5.Dataset`.
        names: the simulations to measure (a run's training simulations).
        radius: the dataset's vessel radius (:func:`thrombojax.data.radius.vessel_radius`).
        start: the rollout's start frame (the dataset's ``skip_frames``).
        quantile: in (0, 1].
        max_stretch: the coherence guard's ``max_stretch`` the tolerance is for (None: rigid).
    Returns:
        ``{"coherence_r", "quantile", "start", "simulations", "pairs", "largest_r",
        "max_stretch"}``: the tolerance, the quantile, the reference frame, the simulations and
        (node, frame) pairs measured, the largest distance among them and ``max_stretch``.
    Raises:
        DatasetError: no simulations, or none with a frame after ``start`` (naming the dataset
            and simulation).
    """
    check_fit_request("coherence", dataset, names, quantile)
    pooled = []
    for name in names:
        sim = dataset[name]
        try:
            pooled.append(clot_deviations(sim.positions, sim.node_type, start, radius,
                                          max_stretch=max_stretch).ravel())
        except DatasetError as err:
            raise DatasetError(f"{dataset.path}: simulation '{name}': {err}") from None
    dev = np.concatenate(pooled)
    if dev.size == 0:
        raise DatasetError(f"{dataset.path}: simulations {', '.join(names)} have no frame after "
                           f"the start frame {start}; give --coherence-tolerance a number")
    return {"coherence_r": float(np.quantile(dev, quantile)), "quantile": float(quantile),
            "start": int(start), "simulations": list(names), "pairs": int(dev.size),
            "largest_r": float(dev.max()), "max_stretch": max_stretch}
