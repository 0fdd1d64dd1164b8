"""Argument types of the ``thrombojax`` command: every number checked when the flags are parsed.

Each factory returns an ``argparse`` ``type=`` callable that rejects non-numbers, NaN and
infinities and values out of range with argparse's one-line usage error (exit status 2) that
names the option, e.g. ``argument --warmup-epochs: must be >= 0, got -1``.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

__all__ = [
    "int_at_least",
    "float_at_least",
    "float_above",
    "angle",
    "auto_radii",
    "NN_INT",
    "POS_INT",
    "NN_FLOAT",
    "POS_FLOAT",
    "output_flags",
]


def _number(text: str, kind: type) -> float:
    try:
        value = kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"must be {'an integer' if kind is int else 'a number'}, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def int_at_least(low: int) -> Callable[[str], int]:
    """An integer ``>= low``."""
    def parse(text: str) -> int:
        value = int(_number(text, int))
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {value}")
        return value
    parse.__name__ = f"integer >= {low}"
    return parse


def float_at_least(low: float) -> Callable[[str], float]:
    """A finite float ``>= low``."""
    def parse(text: str) -> float:
        value = _number(text, float)
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low:g}, got {value:g}")
        return value
    parse.__name__ = f"number >= {low:g}"
    return parse


def float_above(low: float) -> Callable[[str], float]:
    """A finite float ``> low``."""
    def parse(text: str) -> float:
        value = _number(text, float)
        if value <= low:
            raise argparse.ArgumentTypeError(f"must be > {low:g}, got {value:g}")
        return value
    parse.__name__ = f"number > {low:g}"
    return parse


def angle(text: str) -> float:
    """An angle in radians, ``>= 0`` and finite (also ``pi``, ``pi/2``, ``0.5pi``, ``90deg``)."""
    from thrombojax.errors import ConfigError
    from thrombojax.train.config import parse_angle

    try:
        value = parse_angle(text)
    except ConfigError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be a finite angle >= 0, got {text!r}")
    return value


# argument types: numbers are checked (finite, in range) when the flags are parsed
NN_INT, POS_INT = int_at_least(0), int_at_least(1)
NN_FLOAT, POS_FLOAT = float_at_least(0.0), float_above(0.0)


def auto_radii(text: str) -> float | str:
    """``auto`` or a tolerance in vessel radii ``>= 0`` (``thrombojax rollout --centring`` and
    ``--coherence-tolerance``)."""
    return "auto" if text == "auto" else NN_FLOAT(text)


def output_flags(p, force_help: str) -> None:
    """``--force`` and ``--quiet``: the same two flags on every writing command."""
    p.add_argument("--force", action="store_true", help=f"{force_help} (never an input file)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
