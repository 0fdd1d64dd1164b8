"""How far a model's compiled step is from the matrix-product rate this CPU reaches.

For the study configs' rollout step (graph + model + integration, :func:`make_step`) this
script prints the floating-point operations XLA counts in the compiled program
(``compiled.cost_analysis()["flops"]``), the step's median time (compiled as thrombojax's
rollouts compile it, :func:`thrombojax.xla_options.jit`) and the rate that makes, beside the
rate of a plain dense layer of the model's dominant shape, ``relu([E, H] @ [H, H])`` with
``E = nodes x K`` edge rows (MeshGraphNet's edge MLPs; ``K`` the neighbour cap, ``H`` the
hidden width), with and without thrombojax's CPU options. ``flops / dense rate`` is the time
the step would take if all of it ran at that dense layer's rate: a floor for a model whose
work is such products, and so the smallest step time this software stack can reach on this
machine without doing less arithmetic.

Usage::

    python benchmarks/flop_bound.py [--models mgn] [--sizes 977 2048] [--calls 15]
                                    [--out FILE.md]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import jax
import jax.numpy as jnp

from thrombojax.cli.allocator import reexec_script_with_tcmalloc
from thrombojax.eval.tables import environment
from thrombojax.io.outputs import refuse_targets
from thrombojax.models import create_model, get_config
from thrombojax.simulator.step import make_step
from thrombojax.xla_options import cpu_compiler_options
from thrombojax.xla_options import jit as xla_jit

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cpu_options import STATS, finish_report, report_header, synthetic_state  # noqa: E402

__all__ = ["step_flops", "dense_rate", "main"]


def _median_ms(fn, calls: int) -> float:
    fn()  # warm
    times = []
    for _ in range(calls):
        t = time.perf_counter()
        fn()
        times.append(1e3 * (time.perf_counter() - t))
    return statistics.median(times)


def step_flops(model_name: str, n: int, calls: int, tiny: bool = False) -> dict:
    """GFLOP of the compiled rollout step and its median time (ms), thrombojax's options."""
    model = create_model(model_name, get_config(model_name, tiny=tiny))
    _, state = synthetic_state(n)
    step = make_step(model)
    params = step.init(jax.random.key(0), *state)
    compiled = xla_jit(step, model=model_name).lower(params, STATS, *state).compile()
    cost = compiled.cost_analysis()
    cost = cost[0] if isinstance(cost, list) else cost
    ms = _median_ms(lambda: jax.block_until_ready(compiled(params, STATS, *state)), calls)
    return {"gflop": float(cost["flops"]) / 1e9, "ms": ms,
            "hidden": int(model.config.hidden), "k": int(model.config.max_neighbors)}


def dense_rate(rows: int, width: int, options: dict, calls: int) -> float:
    """GFLOP/s of ``relu(x @ w)``, ``x: [rows, width]``, ``w: [width, width]``."""
    x = jax.random.normal(jax.random.key(0), (rows, width))
    w = jax.random.normal(jax.random.key(1), (width, width)) / width ** 0.5
    f = jax.jit(lambda x, w: jnp.maximum(x @ w, 0.0), compiler_options=options or None)
    ms = _median_ms(lambda: jax.block_until_ready(f(x, w)), calls)
    return 2.0 * rows * width * width / (ms * 1e-3) / 1e9


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--models", nargs="+", default=["mgn"], choices=["mgn"],
                        help="models whose work is dense layers on edge rows")
    parser.add_argument("--sizes", nargs="+", type=int, default=[977, 2048])
    parser.add_argument("--calls", type=int, default=15)
    parser.add_argument("--tiny", action="store_true", help="tiny configs (a smoke run)")
    parser.add_argument("--out", default=None, help="markdown file to write (atomically)")
    parser.add_argument("--force", action="store_true", help="replace an existing --out")
    args = parser.parse_args(argv)
    refuse_targets(parser, (args.out,), force=args.force, what="report")
    out = report_header("benchmarks/flop_bound.py", environment())
    out += ["", "| model | nodes | step GFLOP (XLA count) | step ms (median) | step GFLOP/s | "
           "dense [E, H] x [H, H] GFLOP/s: XLA defaults / thrombojax's options | "
           "floor ms at the better dense rate | step / floor |",
           "|---|---|---|---|---|---|---|---|"]
    print("\n".join(out), flush=True)
    for name in args.models:
        for n in args.sizes:
            s = step_flops(name, n, args.calls, args.tiny)
            rows = n * s["k"]
            rates = [dense_rate(rows, s["hidden"], o, args.calls)
                     for o in ({}, cpu_compiler_options(name))]
            floor = s["gflop"] / max(rates) * 1e3
            out.append(f"| {name} | {n:,} | {s['gflop']:.4g} | {s['ms']:.4g} | "
                       f"{s['gflop'] / s['ms'] * 1e3:.3g} | {rates[0]:.3g} / {rates[1]:.3g} | "
                       f"{floor:.4g} | {s['ms'] / floor:.2f} |")
            print(out[-1], flush=True)
    finish_report(out, args.out)


if __name__ == "__main__":
    reexec_script_with_tcmalloc(__file__, sys.argv[1:])
    main()
