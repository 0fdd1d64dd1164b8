"""The centring pull's tolerance from data: how far the true clots lie off the vessel's middle.

``thrombojax train --centre-pull K --centre-tolerance auto`` measures, on every frame of the
run's training simulations that rollouts run on (from the dataset's ``skip_frames``), the
offset of the true clot's centroid from the middle of the vessel's cross-section as the step's
prior reads it (:func:`thrombojax.graph.section.section_offset`, with the axis of the prior's
width, on the nodes a training sample holds: ``nodes_per_sample`` of them when the run
subsamples), and takes their ``quantile`` as the tolerance: the pull then leaves the true
clots alone in all but ``1 - quantile`` of those frames, and a dataset whose clots run off the
middle gets a wide tolerance. The fit is recorded in the run's ``config.json``
(``centre_tolerance_fit``).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.data.augment import subsample_indices
from thrombojax.errors import DatasetError
from thrombojax.graph.section import section_offset
from thrombojax.graph.vessel_axis import vessel_axis
from thrombojax.graph.wall_nodes import wall_patches

__all__ = ["AUTO_QUANTILE", "pull_offsets", "fit_pull_tolerance", "centre_tolerance_of",
           "fit_config_tolerance"]

AUTO_QUANTILE: float = 0.5
"""The share of the training frames whose true clot ``--centre-tolerance auto`` leaves alone:
the median, the offset a true clot typically has. Measured on the frames rollouts run on: on
BendVessel (16 training simulations) the median is 0.001 r and the 95th percentile 0.11 r,
which is the clot still settling into the middle after it enters; with 0.11 r the prior alone
leaves 12-14 % of the clot outside on the held-out simulations, against 3-4 % at 0
(``experiments/results/ladder_budget/bendvessel_pull/README.md``). On ClotEntry (7 simulations,
2,048 nodes) the median is 0.14 r, the 95th percentile 0.31 r."""


@functools.partial(jax.jit, static_argnames=("radius", "axis_width"))
def _offsets(positions: jax.Array, node_type: jax.Array, *, radius: float,
             axis_width: float) -> tuple[jax.Array, jax.Array]:
    """The compiled body of :func:`pull_offsets` (one compilation per shape and widths, not
    per call): the wall searched once on the first frame, then a map over the frames."""
    mask = jnp.ones(node_type.shape[0], bool)
    patch = wall_patches(positions[0], node_type, mask)

    def one(x):
        axis = vessel_axis(x, node_type, mask, radius=axis_width, patch=patch)
        e, ok = section_offset(x, node_type, mask, unit=radius, axis=axis)
        return jnp.sqrt(jnp.sum(e * e)), ok

    return jax.lax.map(one, positions)


def pull_offsets(positions: np.ndarray, node_type: np.ndarray, *, radius: float,
                 axis_width: float) -> tuple[np.ndarray, np.ndarray]:
    """``([T] offset, [T] ok)``: the clot centroid's offset from the cross-section's middle in
    every frame of ``positions [T, N, 3]``, in units of ``radius`` (the vessel radius, units of
    the positions), and whether the section has a middle there; ``axis_width``: the prior's
    axis width (units of the positions). One compiled map over the frames, the rigid vessel's
    wall searched once."""
    off, ok = _offsets(jnp.asarray(positions, jnp.float32), jnp.asarray(node_type),
                       radius=float(radius), axis_width=float(axis_width))
    return np.asarray(off) / radius, np.asarray(ok)


def fit_pull_tolerance(dataset: Any, names: Sequence[str], *, radius: float, axis_width: float,
                       skip: int, nodes: int | None, seed: int,
                       quantile: float = AUTO_QUANTILE) -> dict[str, Any]:
    """The tolerance (vessel radii) that leaves ``quantile`` of the true clots' frames of the
    simulations ``names`` alone (see the module docstring).

    Args:
        dataset: an open :class:`thrombojax.io.hdf5.Dataset`. names: the training simulations.
        radius: the vessel radius, axis_width: the prior's axis width (dataset units).
        skip: frames skipped at the start (the run's ``skip_frames``).
        nodes: nodes per training sample (None or at least the simulation's: all nodes).
        seed: the subsample's seed. quantile: in (0, 1].
    Returns:
        ``{"centre_tolerance_r", "quantile", "skip_frames", "simulations", "frames",
        "largest_r"}``.
    Raises:
        DatasetError: no simulations, or no frame with a middle (naming the dataset).
    """
    if not 0.0 < quantile <= 1.0:
        raise DatasetError(f"centre tolerance fit: quantile must be in (0, 1], got {quantile}")
    if not names:
        raise DatasetError(f"{dataset.path}: no training simulations to fit the centring pull's "
                           "tolerance on")
    pooled = []
    for name in names:
        pos, nt = np.asarray(dataset.positions(name)), np.asarray(dataset.node_type(name))
        if nodes is not None and nodes < nt.size:
            idx = subsample_indices(seed, nt, nodes)
            pos, nt = pos[:, idx], nt[idx]
        off, ok = pull_offsets(pos[skip:], nt, radius=radius, axis_width=axis_width)
        pooled.append(off[ok])
    offsets = np.concatenate(pooled)
    if offsets.size == 0:
        raise DatasetError(f"{dataset.path}: simulations {', '.join(names)}: no frame whose "
                           "clot lies in a cross-section with a middle; give "
                           "--centre-tolerance a number")
    return {"centre_tolerance_r": float(np.quantile(offsets, quantile)),
            "quantile": float(quantile), "skip_frames": int(skip), "simulations": list(names),
            "frames": int(offsets.size), "largest_r": float(offsets.max())}


def centre_tolerance_of(cfg: Any, dataset: Any, train: Sequence[str]
                        ) -> tuple[float, dict[str, Any] | None]:
    """``(tolerance in vessel radii, the fit or None)`` of a training config: its
    ``centre_tolerance``, fitted on the training simulations ``train`` when it is ``"auto"``
    and the config pulls (``centre_pull > 0``), on the frames rollouts run on (from the
    dataset's ``skip_frames``, or the config's if later); 0 for ``"auto"`` without a pull."""
    if cfg.centre_tolerance != "auto":
        return float(cfg.centre_tolerance), None
    if not cfg.centre_pull > 0:
        return 0.0, None
    fit = fit_config_tolerance(cfg, dataset, train)
    return fit["centre_tolerance_r"], fit


def fit_config_tolerance(cfg: Any, dataset: Any, train: Sequence[str]) -> dict[str, Any]:
    """:func:`fit_pull_tolerance` on the training simulations ``train`` as a training config
    ``cfg`` reads them (its prior's width ``follow_axis``, ``nodes_per_sample``, ``seed``, and
    the frames from the dataset's ``skip_frames`` or the config's if later): the ``auto``
    tolerance of ``thrombojax train`` and of ``thrombojax rollout --centre-pull``."""
    from thrombojax import study
    from thrombojax.data.radius import vessel_radius

    r = float(vessel_radius(dataset))
    skip = max(int(cfg.skip_frames), study.skip_frames(dataset))
    return fit_pull_tolerance(dataset, train, radius=r, axis_width=cfg.follow_axis * r,
                              skip=skip, nodes=cfg.nodes_per_sample, seed=cfg.seed)
