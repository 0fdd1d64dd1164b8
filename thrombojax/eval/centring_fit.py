"""The centring guard's tolerance from data: how far true clots lie from the vessel's middle.

:func:`centroid_offsets` measures, for every frame of a simulation, how far the true clot's
centroid lies across the local axis from the middle of the vessel's cross-section
(:func:`thrombojax.simulator.centring.section_centre` on the simulation's rigid wall, its
triangles when it has them), in vessel radii, and whether the section has a middle there (not
at an open end, where the guard stands aside). :func:`fit_centring` pools the offsets of a set
of simulations (a run's training simulations) and returns their ``quantile`` as the tolerance,
so that the guard leaves the true clots of those simulations alone in all but
``1 - quantile`` of their frames. ``thrombojax rollout --centring auto`` uses it with the run's
training simulations: a dataset whose clots run along the wall gets a wide tolerance, and the
guard then hardly acts.

Measured (``experiments/results/ladder_budget/clotentry_centring/truth_offset.md`` and
``experiments/results/ladder_budget/bendvessel_centring/truth_offset.md``): the 95th percentile
of the training simulations is 0.16 r on ClotEntry (the tolerance picked there on the validation
simulation was 0.15 r) and 0.08 r on BendVessel.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.errors import DatasetError
from thrombojax.simulator.centring import centre_lengths, section_centre
from thrombojax.simulator.wall_build import wall_from_simulation
from thrombojax.types import NodeType

__all__ = ["AUTO_QUANTILE", "centroid_offsets", "check_fit_request", "fit_centring"]

AUTO_QUANTILE: float = 0.95
"""The share of the true clots' frames that ``--centring auto`` leaves alone."""


def check_fit_request(guard: str, dataset: Any, names: Sequence[str], quantile: float) -> None:
    """Refuse a guard-tolerance fit (``fit_<guard>``) with a quantile outside (0, 1] or no
    simulations (naming the dataset)."""
    if not 0.0 < quantile <= 1.0:
        raise DatasetError(f"fit_{guard}: quantile must be in (0, 1], got {quantile}")
    if not names:
        raise DatasetError(f"{dataset.path}: no simulations to fit the {guard} tolerance on")


def centroid_offsets(positions: np.ndarray, node_type: np.ndarray,
                     wall_cells: np.ndarray | None, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """``([T] offset, [T] ok)``: the true clot centroid's offset from the middle of the vessel's
    cross-section in vessel radii, and whether the section has a middle there.

    Args:
        positions: ``[T, N, 3]`` a simulation's frames (any length unit).
        node_type: ``[N]`` node types. wall_cells: the rigid wall's triangles, or None.
        radius: the vessel radius in the positions' unit.
    """
    pos = np.asarray(positions, np.float32)
    node_type = np.asarray(node_type)
    wall = wall_from_simulation(pos[0], node_type, wall_cells)
    cents = jnp.asarray(pos[:, node_type == NodeType.CLOT].mean(axis=1))
    axis_radius, slab, reach = centre_lengths(radius)
    centre, _, ok = jax.jit(jax.vmap(lambda c: section_centre(
        c, wall, axis_radius=axis_radius, slab=slab, reach=reach)))(cents)
    return np.linalg.norm(np.asarray(cents - centre), axis=-1) / radius, np.asarray(ok)


def fit_centring(dataset: Any, names: list[str] | tuple[str, ...], radius: float, *,
                 quantile: float = AUTO_QUANTILE) -> dict[str, Any]:
    """The centring tolerance (vessel radii) that leaves ``quantile`` of the true clots' frames
    of the simulations ``names`` alone.

    Args:
        dataset: an open :class:`thrombojax.io.hdf5.Dataset`.
        names: the simulations to measure (a run's training simulations).
        radius: the dataset's vessel radius (:func:`thrombojax.data.radius.vessel_radius`).
        quantile: in (0, 1].
    Returns:
        ``{"centring_r", "quantile", "simulations", "frames", "largest_r"}``: the tolerance,
        the quantile, the simulations and frames measured and the largest offset among them.
    Raises:
        DatasetError: no simulations, or no frame of them with a middle (naming the dataset).
    """
    check_fit_request("centring", dataset, names, quantile)
    pooled = []
    for name in names:
        sim = dataset[name]
        offset, ok = centroid_offsets(sim.positions, sim.node_type, sim.wall_cells, radius)
        pooled.append(offset[ok])
    offsets = np.concatenate(pooled)
    if offsets.size == 0:
        raise DatasetError(f"{dataset.path}: simulations {', '.join(names)}: no frame whose "
                           "clot lies in a cross-section with a middle; give --centring a number")
    return {"centring_r": float(np.quantile(offsets, quantile)), "quantile": float(quantile),
            "simulations": list(names), "frames": int(offsets.size),
            "largest_r": float(offsets.max())}
