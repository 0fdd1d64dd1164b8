"""Training step with the batch as one flat graph against ``jax.vmap`` over per-sample graphs.

Issue 17, "training as fast as the rollout": does running the study MeshGraphNet once on the
batch's flat graph (:mod:`thrombojax.simulator.flat`: per-sample graphs concatenated, neighbour
indices offset by ``b * N``, one ``segment_sum`` over ``[B*N, K]`` slots) make the training
step (:func:`thrombojax.train.step.make_train_step`: graph, forward, backward, AdamW) faster
than the default ``jax.vmap`` over the samples? The two forms give the same loss and gradients
(``tests/test_flat_batch.py``).

One worker process per case (node count x batch; a fresh process frees the previous case's
memory) compiles both forms (``jax.jit(step).lower(...).compile()``, whose
``memory_analysis()`` gives the compiled peak: temporaries + arguments + outputs - aliased),
runs one warm step of each from the same state (their losses are printed side by side, a check
that both compute the same thing at full size), then ``--rounds`` rounds alternating the forms
(the order flips every round), ``--steps`` timed steps per form and round. A worker whose
compiled peaks (summed over the forms it holds: under tcmalloc the two steps' freed memory was
not shared), times :data:`PEAK_FACTOR`, exceed the memory available (``MemAvailable`` of
``/proc/meminfo``) less a margin compiles but does not run, and the case is reported as such.
``--isolate`` runs every form and round in its own worker (compile, one warm step, the timed
steps; still alternating), so only one step's memory is held at a time: for the cases whose
two forms do not fit together.

Printed and written per case: median and range of the step time per form, the ratio of the
medians (flat / vmap), the range of the per-round ratios (the flat step over the vmap step of the
same round), and whether flat was faster in every round; at the end, whether flat was faster in
every round of every case that ran (the first condition for making it the default;
the other, that repeated runs agree, is judged across runs in the results file).

Inputs are synthetic (``benchmarks/train.py``'s bent tube with a clot blob); the speed depends
on the node count, the neighbour cap and the batch, not on the physics.

Usage::

    python benchmarks/flat_batch.py [--sizes 977 2048] [--batches 8 4] [--rounds 3] [--steps 1]
                                    [--remat] [--isolate] [--out FILE | --append FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.eval.tables import environment
from thrombojax.models.registry import create_model, get_config
from thrombojax.study import training_defaults
from thrombojax.train.schedule import make_optimizer, make_schedule
from thrombojax.train.step import init_state, make_train_step
from thrombojax.types import TargetStats

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from train import synthetic_batch  # noqa: E402  (benchmarks/ is not a package)

__all__ = ["FORMS", "MARGIN_BYTES", "PEAK_FACTOR", "compile_form", "summarise", "main"]

FORMS: tuple[str, ...] = ("vmap", "flat")
"""The two forms: ``jax.vmap`` over per-sample graphs (the default), the flat batch graph."""
MARGIN_BYTES: int = 2 * 2**30
"""Memory left free for the rest of the machine when deciding whether a case can run."""
PEAK_FACTOR: float = 2.0
"""A worker runs only if this times its compiled peaks fits: under tcmalloc the resident memory
of a step outgrew its compiled peak (a 977 x 8 worker was OOM-killed, see the results file)."""


def compile_form(form: str, n_nodes: int, batch: int, remat: bool) -> dict:
    """Compile one form's training step on a synthetic batch (study MeshGraphNet).

    Returns: ``{"compiled", "state", "data", "key", "peak", "compile_s"}``.
    """
    model = create_model("mgn", get_config("mgn", remat=remat))
    host = synthetic_batch(batch, n_nodes)
    tx = make_optimizer(make_schedule(training_defaults("mgn")["lr"], 1000, 10))
    state = init_state(model, tx, jax.random.PRNGKey(0), host)
    stats = TargetStats(mean=jnp.zeros(3), std=jnp.full(3, 1e-3))
    step = make_train_step(model, tx, stats, donate=True, flat_batch=form == "flat")
    data, key = jax.tree.map(jnp.asarray, host), jax.random.PRNGKey(1)
    t0 = time.perf_counter()
    compiled = step.lower(state, data, key).compile()
    mem = compiled.memory_analysis()
    peak = (mem.temp_size_in_bytes + mem.argument_size_in_bytes + mem.output_size_in_bytes
            - mem.alias_size_in_bytes)
    return {"compiled": compiled, "state": state, "data": data, "key": key, "peak": int(peak),
            "compile_s": time.perf_counter() - t0}


def _available_bytes() -> int:
    with open("/proc/meminfo") as f:
        info = dict(line.split(":", 1) for line in f)
    return int(info["MemAvailable"].split()[0]) * 1024


def _emit(**msg) -> None:
    print(json.dumps(msg), flush=True)


def _worker(n_nodes: int, batch: int, remat: bool, forms: list[str], rounds: int,
            steps: int) -> None:
    """Compile the forms of one case, check they fit, warm them up, time alternating rounds."""
    ready = {}
    for form in forms:
        ready[form] = compile_form(form, n_nodes, batch, remat)
        _emit(form=form, peak=ready[form]["peak"], compile_s=ready[form]["compile_s"])
    # the sum: tcmalloc keeps what a step frees, and the steps of the two forms did not share
    # it (a run that checked the larger peak alone was OOM-killed at 977 x 8)
    need = PEAK_FACTOR * sum(r["peak"] for r in ready.values())
    avail = _available_bytes()
    if need > avail - MARGIN_BYTES:
        _emit(skipped=f"{PEAK_FACTOR:g} x compiled peaks {need / 1e9:.1f} GB > available "
                      f"{avail / 1e9:.1f} GB - margin {MARGIN_BYTES / 1e9:.1f} GB")
        return
    losses = {}
    for form, r in ready.items():  # the warm step, from the same initial state
        r["state"], metrics = r["compiled"](r["state"], r["data"], r["key"])
        losses[form] = float(metrics["loss"])
    _emit(warm_loss=losses)
    for i in range(rounds):
        order = forms if i % 2 == 0 else forms[::-1]
        out = []
        for form in order:
            r = ready[form]
            for _ in range(steps):
                t0 = time.perf_counter()
                r["state"], metrics = r["compiled"](r["state"], r["data"], r["key"])
                jax.block_until_ready((r["state"], metrics))
                out.append({"form": form, "round": i, "ms": 1e3 * (time.perf_counter() - t0),
                            "finite": bool(np.isfinite(float(metrics["loss"])))})
        _emit(round=out, load=os.getloadavg())


def _run_worker(case: dict, forms: tuple[str, ...], rounds: int, args,
                round_index: int | None = None) -> None:
    """Run one worker process and add what it reports to ``case``."""
    n_nodes, batch = case["nodes"], case["batch"]
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", json.dumps([n_nodes, batch]),
           "--forms", *forms, "--rounds", str(rounds), "--steps", str(args.steps)] + \
          (["--remat"] if args.remat else [])
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)  # inherits LD_PRELOAD
    for line in proc.stdout:
        msg = json.loads(line)
        print(f"#   {n_nodes} x {batch}: {msg}", flush=True)
        if "form" in msg:
            case["peak"].setdefault(msg["form"], msg["peak"])
            case["compile_s"].setdefault(msg["form"], msg["compile_s"])
        if "skipped" in msg:
            case["skipped"] = msg["skipped"]
        if "warm_loss" in msg:
            case.setdefault("warm_loss", {}).update(msg["warm_loss"])
        for t in msg.get("round", []):
            case["times"].append(t if round_index is None else dict(t, round=round_index))
    if proc.wait() != 0:
        case["skipped"] = f"worker exited with {proc.returncode}"


def _run_case(n_nodes: int, batch: int, args) -> dict:
    """Both forms in one worker, or (``--isolate``) every form and round in its own process."""
    case = {"nodes": n_nodes, "batch": batch, "peak": {}, "compile_s": {}, "times": []}
    if not args.isolate:
        _run_worker(case, FORMS, args.rounds, args)
    for i in range(args.rounds if args.isolate else 0):
        for form in FORMS if i % 2 == 0 else FORMS[::-1]:
            if "skipped" not in case:
                _run_worker(case, (form,), 1, args, round_index=i)
    case["load"] = [round(x, 2) for x in os.getloadavg()]
    return case


def summarise(case: dict) -> dict:
    """Medians and ranges per form, ratio of medians, per-round ratios (flat / vmap)."""
    ms = {f: [t["ms"] for t in case["times"] if t["form"] == f] for f in FORMS}
    rounds = sorted({t["round"] for t in case["times"]})
    per_round = [statistics.median(t["ms"] for t in case["times"]
                                   if t["round"] == i and t["form"] == "flat")
                 / statistics.median(t["ms"] for t in case["times"]
                                     if t["round"] == i and t["form"] == "vmap")
                 for i in rounds]
    med = {f: statistics.median(v) for f, v in ms.items()}
    return {"median": med, "range": {f: (min(v), max(v)) for f, v in ms.items()},
            "ratio": med["flat"] / med["vmap"], "round_ratios": (min(per_round), max(per_round)),
            "faster_every_round": max(per_round) < 1.0,
            "finite": all(t["finite"] for t in case["times"])}


def _table(cases: list[dict]) -> list[str]:
    rows = ["| nodes | batch | form | step s median | range | flat / vmap (medians) | "
            "per-round ratios | flat faster every round | compiled peak GB | compile s | "
            "warm-step loss | load after | loss finite |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for case in cases:
        for form in FORMS:
            peak = case["peak"].get(form)
            head = (f"| {case['nodes']} | {case['batch']} | {form} | ")
            tail = (f"{'' if peak is None else f'{peak / 1e9:.2f}'} | "
                    f"{case['compile_s'].get(form, float('nan')):.0f} | ")
            if "skipped" in case or not case["times"]:
                rows.append(head + f"not run: {case.get('skipped', 'no rounds')} | | | | | "
                            + tail + f" | {case['load']} | |")
                continue
            s = summarise(case)
            lo, hi = s["range"][form]
            ratio = (f"{s['ratio']:.2f} | {s['round_ratios'][0]:.2f}-{s['round_ratios'][1]:.2f} "
                     f"| {s['faster_every_round']}") if form == "flat" else " | | "
            rows.append(head + f"{s['median'][form] / 1e3:.2f} | {lo / 1e3:.2f}-{hi / 1e3:.2f} | "
                        + ratio + " | " + tail + f"{case['warm_loss'][form]:.6g} | "
                        f"{case['load']} | {s['finite']} |")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", nargs="+", type=int, default=[977, 2048])
    parser.add_argument("--batches", nargs="+", type=int,
                        default=[int(training_defaults("mgn")["batch_size"]), 4])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--steps", type=int, default=1, help="timed steps per form and round")
    parser.add_argument("--remat", action="store_true", help="the study config with remat=True")
    parser.add_argument("--isolate", action="store_true",
                        help="every form and round in a fresh process (one step's memory at a "
                             "time; set JAX_COMPILATION_CACHE_DIR to compile once)")
    parser.add_argument("--forms", nargs="+", default=list(FORMS), help=argparse.SUPPRESS)
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--out", default=None, help="markdown file to write")
    group.add_argument("--append", default=None, help="markdown file to append this run to")
    parser.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        n_nodes, batch = json.loads(args.worker)
        return _worker(n_nodes, batch, args.remat, args.forms, args.rounds, args.steps)
    env = environment()
    config = "study MeshGraphNet" + (" with remat=True" if args.remat else " (remat off)")
    out = [f"## benchmarks/flat_batch.py on {env['device']}: {config}", "", "```"]
    out += [f"# {k}: {v}" for k, v in env.items()]
    out += [f"# LD_PRELOAD: {os.environ.get('LD_PRELOAD', '(none)')}", "```"]
    print("\n".join(out), flush=True)
    cases = [_run_case(n, b, args) for n in args.sizes for b in args.batches]
    where = ("every form and round in its own process (after one warm step)" if args.isolate
             else "both forms in one process")
    out += ["", f"{args.rounds} rounds x {args.steps} step(s) per form, {where}; forms "
            "alternate, order flipped every round. Load: 1, 5, 15-minute load average when the "
            "case finished.", ""] + _table(cases)
    ran = [summarise(c) for c in cases if "skipped" not in c and c["times"]]
    verdict = (f"flat faster in every round of every case run: "
               f"{bool(ran) and all(s['faster_every_round'] for s in ran)} "
               f"({len(ran)} of {len(cases)} cases run)")
    out += ["", verdict, "",
            f"load (1, 5, 15 min) at the end: {[round(x, 2) for x in os.getloadavg()]}"]
    print("\n".join(out[-len(cases) * 2 - 6:]), flush=True)
    target = args.out or args.append
    if target:
        with open(target, "a" if args.append else "w") as f:
            f.write(("\n" if args.append else "") + "\n".join(out) + "\n")


if __name__ == "__main__":
    main()
