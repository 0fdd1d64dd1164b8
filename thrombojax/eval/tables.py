"""Shared report helpers: markdown tables and the environment every recorded result carries."""

from __future__ import annotations

import datetime
import os
import pathlib
import platform
import sys
from typing import Any

import flax
import jax
import numpy as np
import optax

from thrombojax import __version__
from thrombojax.xla_options import MODEL_CPU_OPTIONS, TRAIN_CPU_OPTIONS, cpu_compiler_options

__all__ = ["markdown_table", "environment", "cpu_model", "measured_line"]


def markdown_table(header: list[str], rows: list[list[Any]]) -> str:
    """A GitHub markdown table; floats printed with 4 significant digits (``%.4g``)."""
    def fmt(v):
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(v) for v in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def _program() -> str:
    """The program's name as a user would type it (``python -m thrombojax`` runs
    ``__main__.py``)."""
    name = pathlib.Path(sys.argv[0]).name
    return "thrombojax" if name == "__main__.py" else name


def cpu_model(cpuinfo: str | None = None) -> str:
    """The processor, as ``/proc/cpuinfo`` names it, with its family and model numbers (a
    virtual machine may name only the vendor, e.g. "AMD EPYC", while different processors
    give different speeds and, from their kernels' rounding, different trained models);
    ``platform.processor()`` where there is no ``/proc/cpuinfo``. ``cpuinfo``: its text (tests).
    """
    if cpuinfo is None:
        try:
            cpuinfo = pathlib.Path("/proc/cpuinfo").read_text()
        except OSError:
            return platform.processor() or "unknown"
    fields = {}
    for line in cpuinfo.splitlines():
        key, sep, value = line.partition(":")
        if sep and key.strip() not in fields:
            fields[key.strip()] = value.strip()
    name = fields.get("model name") or platform.processor() or "unknown"
    numbers = [f"{k} {fields[k]}" for k in ("cpu family", "model") if k in fields]
    return f"{name} ({', '.join(numbers)})" if numbers else name


def environment() -> dict:
    """Device, versions, date, command and machine load: recorded beside every figure.

    The one record of where a result was measured, used by ``thrombojax bench``, the demo,
    the experiment results and the scripts in ``benchmarks/``.
    """
    dev = jax.devices()[0]
    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "command": " ".join([_program(), *sys.argv[1:]]),
        "device": f"{dev.platform}:{getattr(dev, 'device_kind', '')}",
        "n_devices": jax.device_count(),
        "cpu_count": os.cpu_count(),
        "cpu": cpu_model(),
        "load_avg_1_5_15": [round(x, 2) for x in os.getloadavg()],
        # tcmalloc makes a CPU training step faster (docs/performance.md): timings depend on it
        "allocator": "tcmalloc" if "tcmalloc" in os.environ.get("LD_PRELOAD", "") else "default",
        # and so do the CPU compiler options of the compiled paths (thrombojax/xla_options.py)
        "xla_options": {**{m: cpu_compiler_options(m) for m in MODEL_CPU_OPTIONS},
                        **{f"{m} (train)": cpu_compiler_options(m, train=True)
                           for m in TRAIN_CPU_OPTIONS}},
        "python": platform.python_version(),
        "platform": platform.platform(),
        "jax": jax.__version__,
        "jaxlib": getattr(jax.lib, "__version__", None),
        "flax": flax.__version__,
        "optax": optax.__version__,
        "numpy": np.__version__,
        "thrombojax": __version__,
    }


def measured_line(env: dict | None = None) -> str:
    """One sentence of where and how a table was measured, for the foot of a Markdown file:
    date, processor, cores, device, load, allocator, Python and jax versions and the command
    (of :func:`environment`, or ``env`` when given)."""
    env = environment() if env is None else env
    return (f"Measured {env['date']} on {env['cpu']} ({env['cpu_count']} cores, "
            f"{env['device']}, load {env['load_avg_1_5_15'][0]}, allocator "
            f"{env['allocator']}); Python {env['python']}, jax {env['jax']}. "
            f"Command: {env['command']}")
