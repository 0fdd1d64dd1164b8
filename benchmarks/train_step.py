"""Training step before and after each optimisation of issue 17, in one run: time, faults, memory.

Speed. Two long-lived worker processes, one under glibc's malloc and one with tcmalloc preloaded
(``LD_PRELOAD``; the allocator is chosen when a process starts), each compile the jitted training
step (:func:`thrombojax.train.step.make_train_step`: graph, forward, backward, AdamW) of every
case: the study's MeshGraphNet in its plain form (``factorised=False, slot_sum=False``), with
each rewrite alone, with both, and factorised with and without ``remat`` (with it: the
default); the study's Transolver with the plain and the split MPNN message layer, and the split
one plus ``remat``; the study's
Erwin with and without ``remat``; batch 1 (as the peer comparison of issue 17) at
977 (BendVessel) and 2,048 nodes (ClotEntry's sample). Per case a pair of workers is started
(one process holding every case grew past this machine's memory under tcmalloc, which keeps
what it frees) and the parent runs rounds alternating the two (glibc, tcmalloc, glibc, ...);
in a round a worker times ``--steps`` steps. Printed per case: the median and range of the
step time over all rounds, the minor page faults per step (``resource.getrusage().ru_minflt``
deltas around each step) and the ratio to the plain form under the same allocator (to the
model's first case run where its plain form is not among ``--variants``). With
``--pair-remat`` each ``remat`` case runs in one worker with the same variant without it, the
two alternating within every round (order flipped round by round), and the step-time cost of
remat is printed: remat / no remat, ratio of the medians and range of the per-round ratios.

Memory. The compiled peak of the training step (``jax.jit(step).lower(...).compile()
.memory_analysis()``: temporaries + arguments + outputs - aliased) per model at its study batch
(:func:`thrombojax.study.training_defaults`: MeshGraphNet 8, Transolver 16, Erwin 8) and study
config (:func:`thrombojax.models.registry.get_config` defaults) at both node counts, every model
with and without ``remat`` (MeshGraphNet's plain form too); nothing is executed (only the
parameters are initialised, on one sample), so batches that do not fit in this machine's memory
are reported too. Target of issue 17: the ClotEntry MeshGraphNet batch (8 x 2,048 nodes,
K = 32) <= 8 GB.

Inputs are synthetic (``benchmarks/train.py``'s bent tube with a clot blob, scaled coordinates);
the speed depends on the node count and the neighbour cap, not on the physics.

Usage::

    python benchmarks/train_step.py [--rounds 3] [--steps 2] [--sizes 977 2048]
                                    [--variants NAME ...] [--pair-remat]
                                    [--skip-memory | --skip-speed]
                                    [--out benchmarks/results/train_step_cpu.md]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import resource
import statistics
import subprocess
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.cli.allocator import find_tcmalloc
from thrombojax.eval.tables import environment
from thrombojax.models.erwin import ErwinSurrogate
from thrombojax.models.meshgraphnet import MeshGraphNetSurrogate
from thrombojax.models.registry import get_config
from thrombojax.models.transolver import TransolverSurrogate
from thrombojax.study import training_defaults
from thrombojax.train.schedule import make_optimizer, make_schedule
from thrombojax.train.step import init_state, make_train_step
from thrombojax.types import TargetStats

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from train import synthetic_batch  # noqa: E402  (benchmarks/ is not a package)

__all__ = ["VARIANTS", "MEMORY_CASES", "REMAT_OF", "variant_model", "train_step_of",
           "compiled_peak", "main"]

VARIANTS: dict[str, tuple[str, dict, bool]] = {
    # name: (model, module options, remat)
    "mgn plain": ("mgn", {"factorised": False, "slot_sum": False}, False),
    "mgn factorised": ("mgn", {}, False),
    "mgn slot-sum": ("mgn", {"factorised": False, "slot_sum": True}, False),
    "mgn factorised + slot-sum": ("mgn", {"slot_sum": True}, False),
    "mgn factorised + remat (default)": ("mgn", {}, True),
    "transolver plain": ("transolver", {"split_messages": False}, False),
    "transolver split (default)": ("transolver", {}, False),
    "transolver split + remat": ("transolver", {}, True),
    "erwin (default)": ("erwin", {}, False),
    "erwin + remat": ("erwin", {}, True),
}
PLAIN = {"mgn": "mgn plain", "transolver": "transolver plain", "erwin": "erwin (default)"}
MEMORY_CASES: tuple[str, ...] = (
    "mgn factorised", "mgn factorised + remat (default)", "mgn plain",
    "transolver split (default)", "transolver split + remat", "erwin (default)", "erwin + remat",
)
"""The compiled-peak cases, each at its model's study batch."""
REMAT_OF: dict[str, str] = {"mgn factorised + remat (default)": "mgn factorised",
                            "transolver split + remat": "transolver split (default)",
                            "erwin + remat": "erwin (default)"}
"""Each ``remat`` case and the same variant without it (the peak ratio's denominator)."""


class _Options:
    """Build the Flax module with extra attributes (the plain forms of the rewrites)."""

    @property
    def module(self):
        return self.module_cls(config=self.config, **dict(self.options))


@dataclasses.dataclass(frozen=True)
class _MGN(_Options, MeshGraphNetSurrogate):
    options: tuple = ()


@dataclasses.dataclass(frozen=True)
class _Transolver(_Options, TransolverSurrogate):
    options: tuple = ()


@dataclasses.dataclass(frozen=True)
class _Erwin(_Options, ErwinSurrogate):
    options: tuple = ()


_CLASSES = {"mgn": _MGN, "transolver": _Transolver, "erwin": _Erwin}


def variant_model(variant: str):
    """The surrogate of a :data:`VARIANTS` entry (study config)."""
    name, options, remat = VARIANTS[variant]
    config = get_config(name, remat=remat)  # explicit: MeshGraphNet's default is remat
    cls = _CLASSES[name]
    return cls(name=name, config=config, options=tuple(sorted(options.items())))


def train_step_of(variant: str, n_nodes: int, batch: int):
    """``(step, state, batch, key)`` of the jitted training step of one case."""
    model = variant_model(variant)
    host = synthetic_batch(batch, n_nodes)
    tx = make_optimizer(make_schedule(training_defaults(model.name)["lr"], 1000, 10))
    state = init_state(model, tx, jax.random.PRNGKey(0), host)
    stats = TargetStats(mean=jnp.zeros(3), std=jnp.full(3, 1e-3))
    step = make_train_step(model, tx, stats, donate=True)
    return step, state, jax.tree.map(jnp.asarray, host), jax.random.PRNGKey(1)


def compiled_peak(variant: str, n_nodes: int, batch: int) -> dict:
    """Compiled memory of one training step (bytes), without running it."""
    step, state, data, key = train_step_of(variant, n_nodes, batch)
    t0 = time.perf_counter()
    mem = step.lower(state, data, key).compile().memory_analysis()
    peak = (mem.temp_size_in_bytes + mem.argument_size_in_bytes + mem.output_size_in_bytes
            - mem.alias_size_in_bytes)
    return {"temp": mem.temp_size_in_bytes, "peak": peak, "compile_s": time.perf_counter() - t0}


def _worker(cases: list[tuple[str, int]], steps: int) -> None:
    """Compile every case, then time ``steps`` steps of each per line read from stdin."""
    ready = {}
    for variant, n in cases:
        step, state, data, key = train_step_of(variant, n, 1)
        t0 = time.perf_counter()
        for _ in range(2):  # compile + one warm step
            state, metrics = step(state, data, key)
        jax.block_until_ready((state, metrics))
        ready[(variant, n)] = [step, state, data, key]
        print(json.dumps({"compiled": variant, "nodes": n,
                          "s": round(time.perf_counter() - t0, 2)}), flush=True)
    print(json.dumps({"ready": True}), flush=True)
    for i, _ in enumerate(sys.stdin):
        out = []
        items = list(ready.items())
        for (variant, n), entry in items if i % 2 == 0 else items[::-1]:  # flip the order
            step, state, data, key = entry
            for _ in range(steps):
                faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
                t0 = time.perf_counter()
                state, metrics = step(state, data, key)
                jax.block_until_ready((state, metrics))
                ms = 1e3 * (time.perf_counter() - t0)
                faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults
                out.append({"variant": variant, "nodes": n, "ms": ms, "faults": faults,
                            "round": i, "finite": bool(np.isfinite(float(metrics["loss"])))})
            entry[1] = state
        print(json.dumps({"round": out, "load": os.getloadavg()}), flush=True)


def _start_worker(cases, steps, preload: str | None) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k != "LD_PRELOAD"}
    if preload:
        env["LD_PRELOAD"] = preload
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", json.dumps(cases),
           "--steps", str(steps)]
    return subprocess.Popen(cmd, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True)


def _read(proc: subprocess.Popen, until: str) -> dict:
    while line := proc.stdout.readline():
        msg = json.loads(line)
        if until in msg:
            return msg
        print(f"#   {msg}", flush=True)
    raise RuntimeError(f"worker exited with {proc.wait()}")


def _speed(args, tcmalloc: str | None, out: list[str]) -> None:
    allocators = {"glibc": None, "tcmalloc": tcmalloc} if tcmalloc else {"glibc": None}
    results = {name: [] for name in allocators}
    loads = {}
    for n in args.sizes:
        for group in _worker_groups(args.variants, args.pair_remat):
            # one worker pair per case: tcmalloc keeps what it frees, so a process that ran
            # several 2,048-node cases grew past this machine's memory (OOM-killed); with
            # --pair-remat a remat case shares its worker with the same variant without remat
            procs = {}
            for name, lib in allocators.items():
                procs[name] = _start_worker([(v, n) for v in group], args.steps, lib)
                _read(procs[name], "ready")  # one compiles at a time
            for _ in range(args.rounds):
                for name, proc in procs.items():  # alternate the allocators round by round
                    proc.stdin.write("go\n")
                    proc.stdin.flush()
                    msg = _read(proc, "round")
                    results[name] += msg["round"]
            for proc in procs.values():
                proc.stdin.close()
                proc.wait()
            for variant in group:
                loads[(variant, n)] = [round(x, 2) for x in os.getloadavg()]
            print(f"# {group} {n} done, load {loads[(variant, n)]}", flush=True)
    out += ["", f"## Training step, batch 1: {args.rounds} rounds x {args.steps} steps per case "
            "and allocator", "",
            "Cases run one after another; within a case the glibc and tcmalloc workers alternate "
            "round by round" + ("; a remat case shares its workers with the same variant without "
                                "remat, the two alternating within each round (order flipped "
                                "round by round)" if args.pair_remat else "")
            + ". Load: 1, 5, 15-minute load average when the case finished.", "",
            "| model | nodes | variant | allocator | step ms median | range | faults/step "
            "(median) | vs plain, same allocator | load | loss finite |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for n in args.sizes:
        for name, rows in results.items():
            plain_ms = {}
            for variant in args.variants:
                mine = [x for x in rows if x["variant"] == variant and x["nodes"] == n]
                ms = [x["ms"] for x in mine]
                med = statistics.median(ms)
                model = VARIANTS[variant][0]
                if variant == PLAIN[model] or model not in plain_ms:
                    plain_ms[model] = med  # (the first case of a model without its plain one)
                out.append(f"| {model} | {n} | {variant} | {name} | {med:.0f} | "
                           f"{min(ms):.0f}-{max(ms):.0f} | "
                           f"{statistics.median(x['faults'] for x in mine):.0f} | "
                           f"{med / plain_ms[model]:.2f} | {loads[(variant, n)]} | "
                           f"{all(x['finite'] for x in mine)} |")
                print(out[-1], flush=True)
    if args.pair_remat:
        _remat_cost(args, results, out)


def _worker_groups(variants: list[str], pair_remat: bool) -> list[list[str]]:
    """The cases of each worker: one each, or a remat case with its base (``--pair-remat``)."""
    if not pair_remat:
        return [[v] for v in variants]
    groups = [[REMAT_OF[v], v] for v in variants if REMAT_OF.get(v) in variants]
    paired = {v for g in groups for v in g}
    return groups + [[v] for v in variants if v not in paired]


def _remat_cost(args, results: dict, out: list[str]) -> None:
    """Step time with remat over the step time without, per model, allocator and size: the
    ratio of the medians and the range of the per-round ratios (same worker, same round)."""
    out += ["", "### Step-time cost of remat (paired in one worker, order flipped each round)",
            "", "| model | nodes | allocator | no remat ms (median) | remat ms (median) | "
            "remat / no remat (medians) | per-round ratios |", "|---|---|---|---|---|---|---|"]
    for n in args.sizes:
        for name, rows in results.items():
            for remat, base in REMAT_OF.items():
                if remat not in args.variants or base not in args.variants:
                    continue
                ms = {v: [x for x in rows if x["variant"] == v and x["nodes"] == n]
                      for v in (base, remat)}
                med = {v: statistics.median(x["ms"] for x in ms[v]) for v in ms}
                per_round = [
                    statistics.median(x["ms"] for x in ms[remat] if x["round"] == i)
                    / statistics.median(x["ms"] for x in ms[base] if x["round"] == i)
                    for i in sorted({x["round"] for x in ms[remat]})]
                out.append(f"| {VARIANTS[remat][0]} | {n} | {name} | {med[base]:.0f} | "
                           f"{med[remat]:.0f} | {med[remat] / med[base]:.2f} | "
                           f"{min(per_round):.2f}-{max(per_round):.2f} |")
                print(out[-1], flush=True)


def _memory(args, out: list[str]) -> None:
    out += ["", "## Compiled peak memory of the training step (study batches, not executed)", "",
            "| model | nodes | batch | variant | temporaries GB | peak GB | vs no remat | "
            "compile s |", "|---|---|---|---|---|---|---|---|"]
    cases = [v for v in MEMORY_CASES if v in args.variants]
    for n in args.sizes:
        peaks = {}
        for variant in cases:
            model = VARIANTS[variant][0]
            batch = int(training_defaults(model)["batch_size"])
            m = compiled_peak(variant, n, batch)
            peaks[variant] = m["peak"]
            base = REMAT_OF.get(variant)
            ratio = f"{m['peak'] / peaks[base]:.2f}" if base in peaks else ""
            out.append(f"| {model} | {n} | {batch} | {variant} | {m['temp'] / 1e9:.2f} | "
                       f"{m['peak'] / 1e9:.2f} | {ratio} | {m['compile_s']:.0f} |")
            print(out[-1], flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--steps", type=int, default=2, help="timed steps per case and round")
    parser.add_argument("--sizes", nargs="+", type=int, default=[977, 2048])
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS),
                        help="cases to run (default: all)", metavar="NAME")
    parser.add_argument("--pair-remat", action="store_true",
                        help="time each remat case in one worker with the same variant without "
                             "remat, alternating, and print the remat / no remat step-time ratio")
    parser.add_argument("--skip-memory", action="store_true")
    parser.add_argument("--skip-speed", action="store_true")
    parser.add_argument("--out", default=None, help="markdown file to write")
    parser.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        return _worker([tuple(c) for c in json.loads(args.worker)], args.steps)
    tcmalloc = find_tcmalloc()
    env = environment()
    out = [f"# benchmarks/train_step.py on {env['device']}", "", "```"]
    out += [f"# {k}: {v}" for k, v in env.items()]
    out += [f"# tcmalloc: {tcmalloc or 'not installed (glibc only)'}", "```"]
    print("\n".join(out), flush=True)
    if not args.skip_memory:
        _memory(args, out)
    if not args.skip_speed:
        _speed(args, tcmalloc, out)
    out += ["", f"load (1, 5, 15 min) at the end: {[round(x, 2) for x in os.getloadavg()]}"]
    print(out[-1])
    if args.out:
        with open(args.out, "w") as f:
            f.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
