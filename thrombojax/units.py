"""Length units: recorded in every dataset file, carried into runs, checked where they meet.

A dataset records the unit of its coordinates (file attribute ``units``, set by ``--units`` at
import; the built-in solver writes ``"vessel radius"``). A training run records the unit of the
dataset it was trained on (``units`` in ``config.json``). Applying a run to a dataset in another
unit would scale its coordinates silently with the training dataset's map, so
:func:`check_units` refuses it.
"""

from __future__ import annotations

from typing import Any

from thrombojax.errors import ConfigError

__all__ = ["dataset_units", "check_units"]


def dataset_units(dataset: Any) -> str:
    """The dataset's length unit (``""`` when the file does not record one)."""
    return str(getattr(dataset, "attrs", {}).get("units", ""))


def check_units(run_config: dict, dataset: Any, *, run_dir: Any, dataset_path: Any) -> None:
    """Raise :class:`ConfigError` when the run's and the dataset's units are both known and differ.

    Args:
        run_config: the run's ``config.json`` (``units`` may be absent in older runs).
        dataset: the opened dataset. run_dir, dataset_path: for the message.
    """
    trained, given = str(run_config.get("units", "")), dataset_units(dataset)
    if trained and given and trained != given:
        raise ConfigError(
            f"{dataset_path}: coordinates are in '{given}', but the run {run_dir} was trained on "
            f"'{trained}'; convert the coordinates (or re-import with the right --units)")
