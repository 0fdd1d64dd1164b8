"""XLA compiler options for the CPU, per model, applied to thrombojax's compiled hot paths.

Why: on the CPU, XLA (jaxlib 0.10) hands matrix products and many element-wise and reduction
fusions to the YNNPACK library. MeshGraphNet spends almost all of its time in
``[N*K, H] x [H, H]`` products with a small ``H`` (the study's 64), and for it XLA's own
emitters and Eigen products are faster: its rollout step at 2,048 nodes 0.83-0.86x, its
training step 0.91-0.99x / 0.95x at 977 / 2,048 nodes over two runs
(``benchmarks/cpu_options.py``, same process, alternating;
``benchmarks/results/cpu_options_cpu.md``). Erwin's rollout step was 1.06-1.13x *slower*
without YNNPACK but its training step 0.92-0.97x faster, so Erwin gets the option in its
training step only (:data:`TRAIN_CPU_OPTIONS`); Transolver changed within noise and keeps XLA's
defaults: the options are chosen per model and per kind of program (:data:`MODEL_CPU_OPTIONS`).
They change which library multiplies, not what is computed: outputs and gradients agree to
float32 rounding (``tests/test_xla_options.py``).

How: :func:`jit` is ``jax.jit`` that adds :func:`cpu_compiler_options` of the model being
compiled (``compiler_options=``) when the function is called, so the backend is known then and
nothing is decided at import. The model comes from ``model=`` (a factory that knows it) or
from the static learned step passed as the first argument or ``step=`` (the rollouts);
``train=True`` marks a training step (forward, backward and optimiser update). Off the
CPU the options are empty. They are dropped, with one warning, when the installed jaxlib does
not know them (a trivial function is compiled with them once per process), and an option the
user set in ``XLA_FLAGS`` is left to the user. Opt out with ``THROMBOJAX_XLA_OPTIONS=0``
(``docs/performance.md``).
"""

from __future__ import annotations

import functools
import os
import warnings
from collections.abc import Callable, Mapping
from typing import Any

import jax

try:  # whether a call is inside a trace (jax >= 0.4.36); else tracers among the arguments tell
    from jax._src.core import trace_state_clean as _trace_state_clean
except ImportError:
    _trace_state_clean = None

__all__ = ["MODEL_CPU_OPTIONS", "TRAIN_CPU_OPTIONS", "OPT_OUT", "cpu_compiler_options",
           "step_model_name", "jit"]

MODEL_CPU_OPTIONS: Mapping[str, Mapping[str, str]] = {
    # no YNNPACK fusions: dots, element-wise and reductions go to XLA's emitters / Eigen
    "mgn": {"xla_cpu_experimental_ynn_fusion_type": ""},
}
"""The options :func:`jit` adds on the CPU to every compiled program of a model, by model name
(XLA ``DebugOptions`` names and values); a model not named here compiles with XLA's defaults."""
TRAIN_CPU_OPTIONS: Mapping[str, Mapping[str, str]] = {
    # Erwin's training step measured 0.92-0.97x without YNNPACK, its rollout step 1.06-1.13x
    "erwin": {"xla_cpu_experimental_ynn_fusion_type": ""},
}
"""Options added (over :data:`MODEL_CPU_OPTIONS`) to a model's training step only."""
OPT_OUT: str = "THROMBOJAX_XLA_OPTIONS"
"""Set to ``0`` to compile every model with XLA's defaults."""


def _wanted(environ: Mapping[str, str], options: Mapping[str, str]) -> dict[str, str]:
    """``options`` less those the user set in ``XLA_FLAGS``; empty when opted out."""
    if environ.get(OPT_OUT, "") == "0":
        return {}
    flags = environ.get("XLA_FLAGS", "")
    return {k: v for k, v in options.items() if f"--{k}" not in flags}


def cpu_compiler_options(model: str | None = None, train: bool = False) -> dict[str, str]:
    """The compiler options of :func:`jit` for ``model`` on the default backend.

    ``train``: for its training step (adds :data:`TRAIN_CPU_OPTIONS`). Empty off the CPU, for a
    model without options (or ``None``) and when opted out. Checked once per process, model and
    kind, however the arguments are passed: a trivial function is compiled with them; if the
    installed jaxlib refuses one, a warning names it and no option is used.
    ``cpu_compiler_options.cache_clear()`` forgets the choices (tests).
    """
    return _options(model, bool(train))


@functools.cache
def _options(model: str | None, train: bool) -> dict[str, str]:
    chosen = {**MODEL_CPU_OPTIONS.get(model, {}),
              **(TRAIN_CPU_OPTIONS.get(model, {}) if train else {})}
    if not chosen or jax.default_backend() != "cpu":
        return {}
    options = _wanted(os.environ, chosen)
    if not options:
        return {}
    try:
        jax.jit(lambda x: x + 1, compiler_options=options).lower(1.0).compile()
    except Exception as err:  # an unknown option: XLA's INVALID_ARGUMENT, version-specific
        warnings.warn(f"thrombojax: XLA refused the CPU compiler options {sorted(options)} "
                      f"({str(err).splitlines()[0]}); compiling {model} with XLA's defaults",
                      RuntimeWarning, stacklevel=3)
        return {}
    return options


cpu_compiler_options.cache_clear = _options.cache_clear


def step_model_name(*args, **kwargs) -> str | None:
    """The model name of the learned step passed first or as ``step=`` (None if there is none)."""
    step = kwargs.get("step", args[0] if args else None)
    return getattr(getattr(step, "model", None), "name", None)


def _top_level(args: tuple, kwargs: Mapping | None) -> bool:
    """Whether a call with these arguments is not inside a trace: jax's trace state is clean
    (where this jax exposes it), else no tracer is among the arguments."""
    if _trace_state_clean is not None:
        return bool(_trace_state_clean())
    leaves = jax.tree.leaves((args, dict(kwargs or {})))
    tracer = getattr(jax.core, "Tracer", ())  # (): no tracer type to find
    return not any(isinstance(x, tracer) for x in leaves)


class _Jit:
    """``jax.jit(fun, **kwargs)`` with the model's :func:`cpu_compiler_options`, one
    ``jax.jit`` per option set, built at its first use."""

    def __init__(self, fun: Callable, kwargs: dict, model: str | None,
                 model_of: Callable[..., str | None] | None, train: bool = False):
        self._fun, self._kwargs, self._model, self._model_of = fun, kwargs, model, model_of
        self._train = train
        self._jitted: dict[tuple, Any] = {}
        functools.update_wrapper(self, fun)

    def _get(self, args: tuple = (), kwargs: Mapping | None = None):
        model = self._model_of(*args, **(kwargs or {})) if self._model_of else self._model
        # inside another jit the options belong to the outer one: jax refuses them on a
        # nested jit, which is inlined into the outer program anyway
        options = (cpu_compiler_options(model, self._train) if _top_level(args, kwargs)
                   else {})
        key = tuple(sorted(options.items()))
        if key not in self._jitted:
            extra = {"compiler_options": options} if options else {}
            self._jitted[key] = jax.jit(self._fun, **self._kwargs, **extra)
        return self._jitted[key]

    def __call__(self, *args, **kwargs):
        return self._get(args, kwargs)(*args, **kwargs)

    def lower(self, *args, **kwargs):
        """``jax.jit(...).lower`` of the variant these arguments compile with."""
        return self._get(args, kwargs).lower(*args, **kwargs)

    def _cache_size(self) -> int:
        """Compilations held, over every option set."""
        return sum(j._cache_size() for j in self._jitted.values())

    def __getattr__(self, name: str) -> Any:  # eval_shape, trace, ...: the model's variant
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self._get(), name)


def jit(fun: Callable | None = None, *, model: str | None = None,
        model_of: Callable[..., str | None] | None = None, train: bool = False,
        **kwargs) -> Any:
    """``jax.jit`` with thrombojax's CPU compiler options; the other arguments are
    ``jax.jit``'s, also as a decorator (``@functools.partial(jit, static_argnums=0)``).

    Args:
        model: the model name, when the caller knows it (a step factory).
        model_of: else a function of the call's arguments that names it
            (:func:`step_model_name` for functions whose first argument is a learned step).
        train: the function is a training step (its model's :data:`TRAIN_CPU_OPTIONS` too).
    """
    if fun is None:
        return functools.partial(jit, model=model, model_of=model_of, train=train, **kwargs)
    return _Jit(fun, kwargs, model, model_of, train)
