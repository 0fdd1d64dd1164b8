"""Exceptions raised by thrombojax. The CLI turns these into one-line messages and exit code 2."""

__all__ = [
    "ThrombojaxError", "DatasetError", "CapacityOverflowError", "ConfigError", "OutputError",
]


class ThrombojaxError(Exception):
    """Base class of every error thrombojax raises on purpose."""


class DatasetError(ThrombojaxError, ValueError):
    """A dataset file or an imported simulation is malformed.

    The message always names the file, the simulation and the field.
    """


class CapacityOverflowError(ThrombojaxError, RuntimeError):
    """A fixed-capacity buffer (neighbour list, grid cell) overflowed; re-allocation failed."""


class ConfigError(ThrombojaxError, ValueError):
    """An unknown model, preset or option, or an inconsistent configuration."""


class OutputError(ThrombojaxError, FileExistsError):
    """An output would overwrite an input, or an existing output without ``--force``."""
