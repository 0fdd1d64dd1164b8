"""XLA's CPU defaults against XLA without YNNPACK, per model and case, same process, alternating.

:mod:`thrombojax.xla_options` compiles thrombojax's hot paths (training step, rollout, ensemble)
with per-model CPU options (:data:`~thrombojax.xla_options.MODEL_CPU_OPTIONS`); the one option
set measured here turns XLA's YNNPACK fusions off (XLA's own emitters and Eigen matrix products
instead). This script measures what that buys or costs for every model and case, which is how
the models that get it were chosen, in one process: every case is compiled once per option set
(``jax.jit(fn, compiler_options=...)``) and the variants alternate within every round, their
order flipped round by round, so the machine's load falls on all of them alike.

Cases (study configs, :func:`thrombojax.models.registry.get_config`; synthetic inputs, the
bent tube with a clot blob of ``benchmarks/train.py``, batch 1 as in ``benchmarks/peer.py``):

* ``step``: the learned step of a rollout (graph from the positions + model + integration,
  :func:`thrombojax.simulator.step.make_step`); at or above
  :data:`thrombojax.simulator.grid_step.AUTO_GRID_MIN_NODES` nodes on the cell grid sized by
  :func:`~thrombojax.simulator.grid_step.allocate_grid`, as the rollouts use it;
* ``train``: the training step (:func:`thrombojax.train.step.make_train_step`: graph, forward,
  backward, AdamW), buffers not donated so that every variant steps from the same state.

Printed per case: median and range of the call time per variant, the ratio of the medians to
XLA's defaults and the range of the per-round ratios, and whether the outputs agree (the
largest absolute difference of the step's positions or the training loss).

Usage::

    python benchmarks/cpu_options.py [--models mgn transolver erwin] [--cases step train]
        [--sizes 977 2048] [--rounds 5] [--calls 3] [--extra] [--tiny] [--out FILE.md]

``--extra`` adds a third variant, without YNNPACK and with XLA's ``tree_reduction_rewriter``
pass disabled (a candidate; it measured 1.6-2.3x slower for Transolver, so not used). Run it
under tcmalloc (``docs/performance.md``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.cli.allocator import reexec_script_with_tcmalloc
from thrombojax.eval.tables import environment
from thrombojax.io.outputs import atomic_write_text, refuse_targets
from thrombojax.models import create_model, get_config
from thrombojax.simulator.grid_step import AUTO_GRID_MIN_NODES, allocate_grid
from thrombojax.simulator.step import make_step
from thrombojax.study import training_defaults
from thrombojax.train.schedule import make_optimizer, make_schedule
from thrombojax.train.step import init_state, make_train_step
from thrombojax.types import TargetStats
from thrombojax.xla_options import MODEL_CPU_OPTIONS, TRAIN_CPU_OPTIONS

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from train import synthetic_batch  # noqa: E402  (benchmarks/ is not a package)

__all__ = ["variants", "synthetic_state", "build_case", "report_header", "finish_report", "main"]

NO_YNN = MODEL_CPU_OPTIONS["mgn"]
STATS = TargetStats(mean=jnp.zeros(3), std=jnp.full(3, 1e-3), velocity_std=jnp.float32(1e-3))


def variants(extra: bool) -> dict[str, dict]:
    """Option sets by name: XLA's defaults, without YNNPACK (MeshGraphNet's in
    :data:`~thrombojax.xla_options.MODEL_CPU_OPTIONS`) and (``extra``) a candidate."""
    out = {"xla defaults": {}, "no YNNPACK": dict(NO_YNN)}
    if extra:
        out["no YNNPACK, no tree reduction"] = dict(
            NO_YNN, xla_disable_hlo_passes="tree_reduction_rewriter")
    return out


def synthetic_state(n: int):
    """``(host batch, (x_prev, x_cur, node_type, mask))`` of one synthetic sample of ``n``
    nodes (``benchmarks/train.py``'s bent tube with a clot blob)."""
    host = synthetic_batch(1, n)
    frames = host.frames[0]
    return host, (jnp.asarray(frames[0]), jnp.asarray(frames[1]),
                  jnp.asarray(host.node_type[0]), jnp.asarray(host.mask[0]))


def report_header(script: str, env: dict) -> list[str]:
    """The report's first lines: the script, the environment and thrombojax's options."""
    return [f"# {script} on {env['device']}", "", "```", *[f"# {k}: {v}" for k, v in env.items()],
            f"# thrombojax's options by model: {dict(MODEL_CPU_OPTIONS)}",
            f"# and in training steps only: {dict(TRAIN_CPU_OPTIONS)}", "```"]


def finish_report(out: list[str], path: str | None) -> None:
    """Append the load at the end, print it, and write the report atomically to ``path``."""
    out += ["", f"load (1, 5, 15 min) at the end: {[round(x, 2) for x in os.getloadavg()]}"]
    print(out[-1])
    if path:
        atomic_write_text(path, "\n".join(out) + "\n")


def build_case(model_name: str, case: str, n: int, options: dict, tiny: bool = False):
    """``(call, output)``: a compiled, warm call of one case under ``options`` (``tiny``: the
    model's tiny config, for tests); ``output`` maps the call's result to the array compared
    between variants."""
    model = create_model(model_name, get_config(model_name, tiny=tiny))
    host, state = synthetic_state(n)
    if case == "step":
        step = make_step(model)
        if n >= AUTO_GRID_MIN_NODES:
            step = allocate_grid(step, np.asarray(host.frames[0, :2]),
                                 np.asarray(host.node_type[0]))
        params = step.init(jax.random.key(0), *state)
        fn = jax.jit(step, compiler_options=options or None)
        compiled = fn.lower(params, STATS, *state).compile()

        def call():
            return jax.block_until_ready(compiled(params, STATS, *state))

        call()
        return call, lambda r: np.asarray(r.positions)
    tx = make_optimizer(make_schedule(training_defaults(model_name)["lr"], 1000, 10))
    train_state = init_state(model, tx, jax.random.PRNGKey(0), host)
    step = make_train_step(model, tx, STATS, donate=False).__wrapped__
    data, key = jax.tree.map(jnp.asarray, host), jax.random.PRNGKey(1)
    compiled = jax.jit(step, compiler_options=options or None).lower(
        train_state, data, key).compile()

    def call():
        return jax.block_until_ready(compiled(train_state, data, key))

    call()
    return call, lambda r: np.asarray(r[1]["loss"])


def _ms(x: float) -> str:
    """Milliseconds to three significant figures (whole milliseconds above 1 s)."""
    return f"{x:.0f}" if x >= 1000 else f"{x:.3g}"


def _run(args, out: list[str]) -> None:
    names = variants(args.extra)
    out += ["", f"## {args.rounds} rounds x {args.calls} calls per case and variant", "",
            "Variants alternate within every round, order flipped round by round. Ratio: median "
            "over XLA's defaults' median; per round: the same ratio within each round. "
            "Agreement: the largest absolute difference from XLA's defaults of the step's "
            "positions (scaled units) or of the training loss.", "",
            "| model | case | nodes | " + " | ".join(f"{v} ms median (range)" for v in names)
            + " | " + " | ".join(f"{v} / defaults (per round)" for v in list(names)[1:])
            + " | agreement | load |",
            "|---|---|---|" + "---|" * (2 * len(names) - 1) + "---|---|"]
    for model_name in args.models:
        for case in args.cases:
            for n in args.sizes:
                if n > 4096 and case == "train":
                    continue  # the training step runs the ladder's 2,048-node samples
                t0 = time.perf_counter()
                built = {v: build_case(model_name, case, n, opts, args.tiny)
                         for v, opts in names.items()}
                print(f"# {model_name} {case} {n}: compiled {len(built)} variants in "
                      f"{time.perf_counter() - t0:.0f} s", flush=True)
                outputs = {v: built[v][1](built[v][0]()) for v in names}
                agree = max(float(np.max(np.abs(outputs[v] - outputs["xla defaults"])))
                            for v in names)
                ms = {v: [] for v in names}
                per_round = {v: [] for v in names}
                order = list(names)
                for r in range(args.rounds):
                    this = {}
                    for v in (order if r % 2 == 0 else order[::-1]):
                        times = []
                        for _ in range(args.calls):
                            t = time.perf_counter()
                            built[v][0]()
                            times.append(1e3 * (time.perf_counter() - t))
                        ms[v] += times
                        this[v] = statistics.median(times)
                    for v in names:
                        per_round[v].append(this[v] / this["xla defaults"])
                med = {v: statistics.median(ms[v]) for v in names}
                row = f"| {model_name} | {case} | {n:,} | " + " | ".join(
                    f"{_ms(med[v])} ({_ms(min(ms[v]))}-{_ms(max(ms[v]))})" for v in names)
                row += " | " + " | ".join(
                    f"{med[v] / med['xla defaults']:.2f} ({min(per_round[v]):.2f}-"
                    f"{max(per_round[v]):.2f})" for v in list(names)[1:])
                row += f" | {agree:.1e} | {[round(x, 2) for x in os.getloadavg()]} |"
                out.append(row)
                print(row, flush=True)
                del built


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--models", nargs="+", default=["mgn", "transolver", "erwin"],
                        choices=["mgn", "transolver", "erwin"])
    parser.add_argument("--cases", nargs="+", default=["step", "train"], choices=["step", "train"])
    parser.add_argument("--sizes", nargs="+", type=int, default=[977, 2048],
                        help="node counts (above 4,096 the step case only, on the cell grid)")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--calls", type=int, default=3, help="timed calls per variant and round")
    parser.add_argument("--extra", action="store_true",
                        help="also time the candidate with the tree-reduction pass disabled")
    parser.add_argument("--tiny", action="store_true", help="tiny model configs (a smoke run)")
    parser.add_argument("--out", default=None, help="markdown file to write (atomically)")
    parser.add_argument("--force", action="store_true", help="replace an existing --out")
    args = parser.parse_args(argv)
    refuse_targets(parser, (args.out,), force=args.force, what="report")
    if jax.default_backend() != "cpu":
        parser.error("this benchmark compares CPU compiler options; the default backend is "
                     f"{jax.default_backend()}")
    out = report_header("benchmarks/cpu_options.py", environment())
    print("\n".join(out), flush=True)
    _run(args, out)
    finish_report(out, args.out)


if __name__ == "__main__":
    reexec_script_with_tcmalloc(__file__, sys.argv[1:])
    main()
