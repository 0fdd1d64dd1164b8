"""The study thrombojax reproduces, in one place: its datasets, training settings and tables.

The MSc study *An Exploratory Study into using Machine-Learning for Fast Step-by-step Emulation
of Numerical Mechanical Thrombectomy Simulations for Ischemic Stroke* trained MeshGraphNet,
Transolver and Erwin on two private Abaqus datasets. Everything the package needs to know about
it lives here and nowhere else:

* :data:`DATASETS`: the two dataset kinds (frames, nodes, the Abaqus wall time per simulation,
  the frames skipped before rollouts). A dataset file records its own ``kind`` and
  ``skip_frames`` as attributes (written by ``thrombojax generate`` and ``thrombojax import``);
  :func:`dataset_kind` and :func:`skip_frames` read them, nothing is guessed from a file name.
* :data:`TRAINING`: the study's batch size and learning rate per model, the defaults of
  :class:`thrombojax.train.config.TrainConfig` (model configs hold architecture only; the
  architecture defaults of each model config are the study's too).
* :data:`TEST_MSE` and :data:`ROLLOUT_TIME_S`: the published tables our results are shown beside.

Which frames are skipped where: the single-step metric (``thrombojax evaluate``) and training use
every window by default, as in the study's test-MSE table; rollouts start after the dataset's
``skip_frames`` (the clot is still entering the vessel before), as in the study's rollouts.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

__all__ = [
    "DatasetKind",
    "DATASETS",
    "UNKNOWN_KIND",
    "TRAINING",
    "TEST_MSE",
    "ROLLOUT_TIME_S",
    "dataset_kind",
    "skip_frames",
    "training_defaults",
]


@dataclasses.dataclass(frozen=True)
class DatasetKind:
    """One of the study's datasets.

    Attributes:
        name: ``bendvessel`` or ``clotentry``.
        n_sims: simulations. n_frames: frames per simulation. n_nodes: nodes per frame.
        abaqus_s: the study's Abaqus wall time per simulation (4 cores of a Ryzen 7900X).
        skip_frames: leading frames skipped before rollouts.
        rollout_nodes: nodes a rollout runs on (ClotEntry: a fixed subset of 2,048).
        rollout_steps: predicted frames of one timed rollout (the study's timing: 35 steps of
            BendVessel, 160 of ClotEntry, scaled to the full simulation length).
    """

    name: str
    n_sims: int
    n_frames: int
    n_nodes: int
    abaqus_s: float
    skip_frames: int
    rollout_nodes: int
    rollout_steps: int


DATASETS: Mapping[str, DatasetKind] = {
    "bendvessel": DatasetKind("bendvessel", 20, 40, 977, 180.0, 5, 977, 35),
    "clotentry": DatasetKind("clotentry", 10, 200, 27_000, 1500.0, 40, 2048, 160),
}

UNKNOWN_KIND = "unknown"
"""The ``kind`` of a dataset that is neither of the study's (e.g. an import of another solver)."""

TRAINING: Mapping[str, Mapping[str, float]] = {
    "mgn": {"batch_size": 8, "lr": 1e-3},  # printed "10E-04" in the thesis table
    "transolver": {"batch_size": 16, "lr": 1e-4},
    "erwin": {"batch_size": 8, "lr": 1e-4},
    "constant_velocity": {"batch_size": 8, "lr": 1e-4},  # no parameters; for completeness
}
"""The study's batch size and peak learning rate per model (AdamW, 300 epochs, 10 warm-up)."""

TEST_MSE: Mapping[str, Mapping[str, tuple[float, float]]] = {
    "bendvessel": {"erwin": (0.00166, 0.00012), "transolver": (0.02336, 0.01016),
                   "mgn": (0.00469, 0.00052)},
    "clotentry": {"erwin": (0.00799, 0.00044), "transolver": (0.01434, 0.00020),
                  "mgn": (0.00784, 0.00014)},
}
"""Single-step test MSE (scaled coordinates, clot nodes), mean and std over 5 seeds."""

ROLLOUT_TIME_S: Mapping[str, Mapping[str, float]] = {
    "bendvessel": {"erwin": 2.167, "transolver": 0.65, "mgn": 0.56},
    "clotentry": {"erwin": 13.19, "transolver": 4.33, "mgn": 3.77},
}
"""Rollout time per simulation on one A100 (seconds, scaled to the full simulation length)."""


def _attrs(dataset: Any) -> Mapping[str, Any]:
    return getattr(dataset, "attrs", dataset)


def dataset_kind(dataset: Any) -> str:
    """The ``kind`` file attribute of a dataset (``bendvessel``, ``clotentry`` or ``unknown``).

    Args:
        dataset: an open :class:`thrombojax.io.hdf5.Dataset` or its attribute mapping.
    """
    return str(_attrs(dataset).get("kind", UNKNOWN_KIND))


def skip_frames(dataset: Any) -> int:
    """Frames a rollout skips on this dataset: its ``skip_frames`` attribute, else 0."""
    return int(_attrs(dataset).get("skip_frames", 0))


def training_defaults(model_name: str) -> Mapping[str, float]:
    """The study's ``batch_size`` and ``lr`` of a registered model (canonical name)."""
    return TRAINING.get(model_name, TRAINING["constant_velocity"])
