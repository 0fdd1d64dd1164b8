"""The centring pull at rollout time: ``thrombojax rollout --centre-pull K``.

A run trained with the vessel-following prior (``--follow-axis``) can roll out with the prior's
centring pull (:func:`thrombojax.graph.section.centre_pull`) switched on, or set to another
strength, without retraining: the learned step is the run's, with ``centre_pull = K``, its
vessel radius the rolled-out vessel's and its tolerance given in vessel radii or fitted
(``auto``) on the run's training simulations as ``thrombojax train --centre-tolerance auto``
fits it (:func:`thrombojax.train.centre_fit.fit_pull_tolerance`). On BendVessel it keeps the
model's clot inside the vessel about as well as training with the pull does
(``experiments/results/ladder_budget/bendvessel_pull/README.md``, section 3).
"""

from __future__ import annotations

import dataclasses
import pathlib
from typing import Any

from thrombojax.errors import ConfigError
from thrombojax.train.centre_fit import fit_config_tolerance

__all__ = ["rollout_pull", "pull_record", "training_dataset_of"]


def rollout_pull(step: Any, trained: Any, training_ds: Any, *, strength: float | None,
                 tolerance: float | str | None, radius: float, run_dir: Any
                 ) -> tuple[Any, dict[str, Any]]:
    """``(step, record)``: ``step`` with the rollout's centring pull, and what was used.

    Args:
        step: the run's learned step (:attr:`thrombojax.train.state.TrainedModel.step`).
        trained: the :class:`~thrombojax.train.state.TrainedModel` (its config and split).
        training_ds: a callable returning the run's own open dataset (read only for ``auto``).
        strength: ``K`` in (0, 1], or ``None``: the run's own pull (trained, possibly none).
        tolerance: in vessel radii, ``"auto"`` (the median offset of the run's training
            clots, :mod:`thrombojax.train.centre_fit`) or ``None``: ``auto``.
        radius: the rolled-out vessel's radius in the run's scaled units.
        run_dir: for messages.
    Raises:
        ConfigError: a tolerance without a strength, a strength outside (0, 1], or a run
            without the vessel-following prior.
    """
    if strength is None:
        if tolerance is not None:
            raise ConfigError("rollout: --centre-tolerance sets the centring pull's tolerance; "
                              "give the pull's strength with --centre-pull K")
        return step, pull_record(step, at="training" if step.centre_pull > 0 else None)
    if not 0.0 < float(strength) <= 1.0:
        raise ConfigError(f"rollout: --centre-pull must be in (0, 1], got {strength!r}")
    if not step.prior_radius > 0:
        raise ConfigError(f"{run_dir}: --centre-pull tilts the vessel-following prior's "
                          "velocities, and this run was trained without it (train with "
                          "--follow-axis W)")
    fit = None
    if tolerance is None or tolerance == "auto":
        fit = fit_config_tolerance(trained.run.train, training_ds(), trained.split.train)
        tolerance = fit["centre_tolerance_r"]
    pulled = dataclasses.replace(step, centre_pull=float(strength), centre_unit=float(radius),
                                 centre_tolerance=float(tolerance) * float(radius))
    return pulled, pull_record(pulled, at="rollout", fit=fit)


def pull_record(step: Any, *, at: str | None, fit: dict | None = None) -> dict[str, Any]:
    """``rollout.json``'s ``centre_pull``: where the pull was set (``"training"``, ``"rollout"``
    or None: no pull), its strength, tolerance in vessel radii and the ``auto`` fit."""
    unit = step.centre_unit
    return {"at": at, "strength": float(step.centre_pull) if at else 0.0,
            "tolerance_r": float(step.centre_tolerance / unit) if at and unit > 0 else None,
            "fit": fit}


def training_dataset_of(trained: Any, ds: Any, dataset_path: Any, run_dir: Any,
                        option: str) -> Any:
    """The run's own dataset (``ds`` when that is the dataset being rolled out), whose training
    simulations an ``auto`` option (``option``, e.g. ``--centring``) is fitted on."""
    from thrombojax.io.hdf5 import open_dataset

    own = pathlib.Path(trained.run.dataset)
    if own.is_file() and own.resolve() == pathlib.Path(dataset_path).resolve():
        return ds
    if own.is_file():
        return open_dataset(own)
    raise ConfigError(f"{run_dir}: {option} auto measures the run's training simulations "
                      f"in its dataset {own}, which is not there; give {option} a number")
