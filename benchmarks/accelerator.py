"""thrombojax on an accelerator: the cases of ``benchmarks/peer.py`` at each matmul precision.

The same cases and synthetic inputs as the thrombojax side of ``benchmarks/peer.py``
(``benchmarks/peer_jax.py``: study configs, batch 1): the rollout step, the N-step compiled
rollout, graph + forward at full resolution (27,000 nodes, cell grid) and the train step (graph,
forward, backward, AdamW). Each case is compiled and timed under every matmul precision given
(``jax.default_matmul_precision`` with an algorithm preset of ``jax.lax.DotAlgorithmPreset``;
``--precisions`` time every case, ``--step-precisions`` the rollout step and the train step):

* ``F32_F32_F32``: full float32 products (the reference);
* ``default``: what a user gets without setting anything (XLA's choice for float32 products);
* ``TF32_TF32_F32``: TensorFloat-32 inputs, float32 accumulation (Ampere and later GPUs);
* ``BF16_BF16_F32``: bfloat16 inputs, float32 accumulation.

Parameters, activations, scatter sums and the optimizer stay float32: only the inputs of the
matrix products are rounded. Beside the time the report gives how far the step's learned part
moves from the float32 one: ``dev`` = ||a_p - a_F32|| / ||a_F32|| with ``a = s_{t+1} - 2 s_t +
s_{t-1}`` of the rollout step (random-initialised models; the single-step MSE of a *trained*
model per precision is measured by ``experiments/gpu_ladder.py``).

Results are written after every case (``--out`` markdown and a ``.json`` beside it), so a run
stopped at a time limit keeps what it measured. The header records device, versions, date,
command and load. Runs on any JAX backend; on a CPU the precisions other than float32 are
rejected or ignored by XLA (recorded as an error or as the same time).

Usage::

    PYTHONPATH=. python benchmarks/accelerator.py [--models mgn transolver erwin]
        [--cases step rollout forward train] [--sizes 977 2048] [--forward-nodes 27000]
        [--precisions F32_F32_F32 default] [--step-precisions TF32_TF32_F32 BF16_BF16_F32]
        [--repeats 20]
        [--out benchmarks/results/accelerator_h100.md]
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import statistics
import sys
import tempfile
import time

import jax
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from peer_common import CASE_LABELS, read_inputs, write_inputs  # noqa: E402
from peer_jax import prepare  # noqa: E402

from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.io.outputs import atomic_write_text, refuse_targets  # noqa: E402

PRECISIONS = ("F32_F32_F32", "default")
STEP_PRECISIONS = ("TF32_TF32_F32", "BF16_BF16_F32")
CASES = ("step", "rollout", "forward", "train")
MODELS = ("mgn", "transolver", "erwin")


def _acceleration(inp, positions) -> np.ndarray:
    return np.asarray(positions, np.float64) - 2.0 * inp.x_cur + inp.x_prev


def measure(model: str, kind: str, n: int, inputs: str, args, precision: str) -> dict:
    """Compile and time one case under one matmul precision; the step case also returns the
    learned acceleration (for the deviation from float32)."""
    spec = {"cases": [[model, kind, n]], "inputs": {str(n): inputs}, "tiny": args.tiny,
            "repeats": args.repeats, "rollout_steps": args.rollout_steps}
    with jax.default_matmul_precision(precision):
        t0 = time.perf_counter()
        (case,) = prepare(spec)
        prep_s = time.perf_counter() - t0
        times, out = [], None
        for _ in range(args.repeats if kind != "rollout" else max(args.repeats // 4, 3)):
            t = time.perf_counter()
            out = case.run()
            times.append((time.perf_counter() - t) * 1e3)
    ms = statistics.median(times)
    row = {"model": model, "case": kind, "nodes": n, "precision": precision,
           "prepare_s": round(prep_s, 2), "median_ms": ms, "min_ms": min(times),
           "max_ms": max(times), "per_step_ms": ms / case.model_steps, **case.info}
    if kind == "step":
        row["_accel"] = out
    return row


def report(rows: list[dict], envs: list[dict], *, rollout_steps: int, tiny: bool = False) -> str:
    """The markdown report: per-step milliseconds per model and precision, the deviations.

    ``envs`` holds one environment record per run whose rows are shown (``--merge`` joins
    several runs of one machine); columns and precisions are those present in ``rows``.
    """
    lines = ["# thrombojax on an accelerator, per matmul precision", ""]
    for i, env in enumerate(envs):
        lines += [f"{'run ' + str(i + 1) + ': ' if len(envs) > 1 else ''}device "
                  f"`{env['device']}`, jax {env['jax']}, jaxlib {env['jaxlib']}, "
                  f"flax {env['flax']}, Python {env['python']}, {env['cpu_count']} CPUs, "
                  f"load {env['load_avg_1_5_15']}, {env['date']}, command: "
                  f"`{env['command']}`", ""]
    lines += ["Median milliseconds per call (rollout: per learned step of the "
              f"{rollout_steps}-step compiled rollout), batch 1, study configs"
              f"{' (tiny)' if tiny else ''}; range and compile time in the JSON beside this "
              "file; `-`: not measured. `dev`: relative deviation of the step's learned "
              "acceleration from the first precision of its run (random-initialised model).", ""]
    order = {k: i for i, k in enumerate(CASES)}
    cols = sorted({(r["case"], r["nodes"]) for r in rows}, key=lambda c: (order[c[0]], c[1]))
    precisions = list(dict.fromkeys(r["precision"] for r in rows))
    lines.append("| model | precision | " + " | ".join(
        f"{CASE_LABELS[k]} {n}" for k, n in cols) + " | dev (step) |")
    lines.append("|---|---|" + "---|" * (len(cols) + 1))
    for model in MODELS:
        for prec in precisions:
            got = {(r["case"], r["nodes"]): r for r in rows
                   if r["model"] == model and r["precision"] == prec}
            if not got:
                continue
            cells = []
            for k, n in cols:
                r = got.get((k, n))
                cells.append("-" if r is None else "error" if "error" in r
                             else f"{r['per_step_ms']:.2f}")
            devs = [r["dev"] for r in got.values() if "dev" in r]
            dev = ", ".join(f"{d:.1e}" for d in devs) if devs else "-"
            lines.append(f"| {model} | {prec} | " + " | ".join(cells) + f" | {dev} |")
    errors = sorted({r["error"] for r in rows if "error" in r})
    if errors:
        lines += ["", "Errors (the cells marked error):", ""] + [f"- {e}" for e in errors]
    return "\n".join(lines) + "\n"


def merge(paths: list[str], out: pathlib.Path) -> str:
    """Join the JSON results of several runs (one machine, e.g. device calls cut by a time
    limit) into one report at ``out`` (and its ``.json``)."""
    envs, rows = [], []
    for i, path in enumerate(paths):
        got = json.loads(pathlib.Path(path).read_text())
        envs.append(got["env"])
        rows += [{**r, "run": i + 1} for r in got["rows"]]
    steps = {e.get("rollout_steps", 40) for e in envs}
    text = report(rows, envs, rollout_steps=max(steps))
    atomic_write_text(out.with_suffix(".json"), json.dumps({"envs": envs, "rows": rows},
                                                            indent=1))
    atomic_write_text(out, text)
    return text


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--models", nargs="+", default=list(MODELS), choices=MODELS)
    p.add_argument("--cases", nargs="+", default=list(CASES), choices=CASES)
    p.add_argument("--sizes", nargs="+", type=int, default=[977, 2048])
    p.add_argument("--forward-nodes", type=int, default=27000)
    p.add_argument("--rollout-steps", type=int, default=40)
    p.add_argument("--precisions", nargs="+", default=list(PRECISIONS),
                   help="matmul precisions timed on every case (the first is the reference of dev)")
    p.add_argument("--step-precisions", nargs="*", default=list(STEP_PRECISIONS),
                   help="matmul precisions timed on the step and train cases only")
    p.add_argument("--repeats", type=int, default=20, help="timed calls per case (median)")
    p.add_argument("--tiny", action="store_true", help="tiny configs (smoke run)")
    p.add_argument("--out", help="markdown report (a .json with every timing beside it)")
    p.add_argument("--force", action="store_true", help="replace an existing report")
    p.add_argument("--merge", nargs="+", metavar="JSON",
                   help="measure nothing: join these runs' JSON results into --out")
    args = p.parse_args(argv)
    out = pathlib.Path(args.out) if args.out else None
    refuse_targets(p, (out, out.with_suffix(".json")) if out else (), force=args.force,
                   inputs=args.merge or (), what="report")
    if args.merge:
        if out is None:
            raise SystemExit("accelerator: --merge needs --out")
        print(merge(args.merge, out))
        return 0
    env = {**environment(), "rollout_steps": args.rollout_steps}
    print(f"device {env['device']}, jax {env['jax']}", flush=True)
    rows: list[dict] = []

    def write(rows: list[dict]) -> str:
        return report(rows, [env], rollout_steps=args.rollout_steps, tiny=args.tiny)

    with tempfile.TemporaryDirectory() as tmp:
        inputs = {}
        for n in {*args.sizes, args.forward_nodes}:
            inputs[n] = os.path.join(tmp, f"inputs_{n}.npz")
            write_inputs(inputs[n], n)
        samples = {n: read_inputs(path) for n, path in inputs.items()}
        reference: dict = {}
        plan = [(p, list(args.cases)) for p in args.precisions] + [
            (p, [k for k in args.cases if k in ("step", "train")]) for p in args.step_precisions]
        for prec, kinds in plan:
            for model in args.models:
                for kind in kinds:
                    if kind == "forward" and model == "erwin":
                        continue  # the table has no Erwin forward
                    for n in ([args.forward_nodes] if kind == "forward" else args.sizes):
                        try:
                            row = measure(model, kind, n, inputs[n], args, prec)
                        except Exception as exc:  # noqa: BLE001 - recorded in the report
                            row = {"model": model, "case": kind, "nodes": n, "precision": prec,
                                   "error": f"{type(exc).__name__}: {str(exc)[:200]}"}
                        accel = row.pop("_accel", None)
                        if accel is not None:
                            a = _acceleration(samples[n], accel)
                            ref = reference.setdefault((model, n), a)
                            row["dev"] = float(np.linalg.norm(a - ref) /
                                               max(np.linalg.norm(ref), 1e-30))
                        rows.append(row)
                        print(json.dumps(row), flush=True)
                        if out is not None:
                            out.parent.mkdir(parents=True, exist_ok=True)
                            atomic_write_text(out.with_suffix(".json"),
                                              json.dumps({"env": env, "rows": rows}, indent=1))
                            atomic_write_text(out, write(rows))
    print(write(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
