"""Readable value axes for curves that may span many decades or almost none.

Matplotlib's log axis labels only the decades, so a curve that stays within one decade gets one
labelled tick or none. :func:`readable_value_axis` picks the scale from the data: a linear axis
when the values span less than a factor of 10, else a log axis labelled at 1-2-5 (or at the
decades when they span more than 3), with short labels such as ``2e-4``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["short_number", "readable_value_axis"]


def short_number(value: float, _pos=None) -> str:
    """``2e-4``, ``0.5``, ``30``: short tick labels, no padded exponent."""
    if value <= 0:
        return ""
    if 1e-2 <= value < 1e3:
        return f"{value:.3g}"
    mant, exp = f"{value:.0e}".split("e")
    return f"{mant}e{int(exp)}"


def readable_value_axis(ax, values, *, log: bool = True) -> None:
    """Set the y scale and ticks of ``ax`` for the plotted ``values`` (module docstring)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    values = np.asarray([v for v in np.ravel(values) if np.isfinite(v)], np.float64)
    positive = values[values > 0]
    if not log or positive.size == 0 or positive.size < values.size:
        ax.set_yscale("linear")
        return
    decades = float(np.log10(positive.max() / positive.min()))
    if decades < 1.0:
        ax.set_yscale("linear")
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 4))
        return
    ax.set_yscale("log")
    subs = (1.0,) if decades > 3 else (1.0, 2.0, 5.0)
    ax.yaxis.set_major_locator(LogLocator(base=10, subs=subs))
    ax.yaxis.set_major_formatter(FuncFormatter(short_number))
    ax.yaxis.set_minor_formatter(NullFormatter())
