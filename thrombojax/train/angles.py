"""Angles as users write them: radians, multiples of pi, degrees (``--max-rotation``, configs)."""

from __future__ import annotations

import math
import re

from thrombojax.errors import ConfigError

__all__ = ["parse_angle"]

_ANGLE = re.compile(r"^\s*(?:(?P<k>[0-9.eE+-]+)\s*\*?\s*)?pi\s*(?:/\s*(?P<d>[0-9.eE+-]+))?\s*$")


def parse_angle(text: str | float) -> float:
    """Parse an angle in radians: ``"3.14159"``, ``"pi"``, ``"pi/2"``, ``"0.5pi"``, ``"90deg"``.

    Returns:
        The angle in radians; a malformed string raises :class:`ConfigError`.
    """
    if isinstance(text, int | float):
        return float(text)
    s = str(text).strip().lower()
    try:
        if s.endswith("deg"):
            return math.radians(float(s[:-3]))
        match = _ANGLE.match(s)
        if match:
            k = float(match.group("k")) if match.group("k") else 1.0
            d = float(match.group("d")) if match.group("d") else 1.0
            return k * math.pi / d
        return float(s)
    except ValueError:
        pass
    raise ConfigError(f"cannot read angle {text!r}: use radians (1.57), pi, pi/2, 0.5pi or 90deg")
