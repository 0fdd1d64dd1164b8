"""Benchmark the built-in solver on its presets: compile time, run time, speed-up over Abaqus.

Usage::

    python benchmarks/solver.py                          # bendvessel (20 sims) + clotentry (1 sim)
    python benchmarks/solver.py --presets clotentry --sims 10   # the whole ClotEntry dataset
    python benchmarks/solver.py --json                   # also write results/solver_<device>.json

Run time excludes compilation (compiled once per preset, then reused for every batch); a
batched preset (BendVessel: 5 simulations per ``vmap``) reports batch time / batch size.
The speed-up is the study's Abaqus wall time per simulation (4 cores of a Ryzen 7900X)
divided by ours. Record the machine load (``uptime``) with the figures: the CPU is shared.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import time
from pathlib import Path

import jax
import numpy as np

from thrombojax.sim.cases import build_case
from thrombojax.sim.generate import compile_cases, simulate_cases
from thrombojax.sim.presets import get_preset


def bench_preset(name: str, n_sims: int | None, seed: int = 0) -> dict:
    """Run ``n_sims`` simulations of a preset; return its figures."""
    preset = get_preset(name)
    n = preset.n_sims if n_sims is None else n_sims
    size = min(preset.batch_size, n)
    compiled, compile_s, sims, t_build = None, 0.0, [], 0.0
    for start in range(0, n, size):
        idx = list(range(start, min(start + size, n)))
        t0 = time.perf_counter()
        cases = [build_case(preset, i, seed) for i in idx + [idx[-1]] * (size - len(idx))]
        t_build += time.perf_counter() - t0
        if compiled is None:
            compiled, _, compile_s = compile_cases(preset, cases)
        sims += simulate_cases(preset, cases, compiled)[: len(idx)]
    run_s = np.array([s.attrs["solver_wall_time_s"] for s in sims])
    a = lambda key: [float(s.attrs[key]) for s in sims]  # noqa: E731
    return {
        "preset": name,
        "simulations": n,
        "batch_size": size,
        "nodes": int(sims[0].n_nodes),
        "clot_nodes": int(np.sum(sims[0].node_type == 1)),
        "clot_tets": int(sims[0].clot_cells.shape[0]),
        "frames": int(sims[0].n_frames - 1),
        "substeps_mean": float(np.mean(a("substeps"))),
        "compile_s": compile_s,
        "case_setup_s_per_sim": t_build / n,
        "run_s_per_sim": float(run_s.mean()),
        "run_s_total": float(run_s.sum()),
        "reference_s_per_sim": preset.reference_wall_time_s,
        "speedup": preset.reference_wall_time_s / float(run_s.mean()),
        "min_J": min(a("min_J")),
        "max_penetration_rel": max(a("max_penetration_rel")),
        "travel_clot_lengths_mean": float(np.mean(a("travel_clot_lengths"))),
        "kinetic_to_elastic_mean": float(np.mean(a("kinetic_to_elastic"))),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=["bendvessel", "clotentry"])
    parser.add_argument(
        "--sims",
        type=int,
        default=None,
        help="simulations per preset (default: all for bendvessel, 1 otherwise)",
    )
    parser.add_argument("--json", action="store_true", help="write results/solver_<device>.json")
    args = parser.parse_args()
    device = jax.devices()[0]
    meta = {
        "device": f"{device.platform}:{device.device_kind}",
        "cpu": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "jax": jax.__version__,
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "load_avg_1_5_15": list(os.getloadavg()),
    }
    print(json.dumps(meta))
    rows = []
    for name in args.presets:
        n = args.sims if args.sims is not None else (None if name.startswith("bend") else 1)
        row = bench_preset(name, n)
        rows.append(row)
        print(
            f"{name:16s} sims {row['simulations']:3d}  nodes {row['nodes']:6d}  frames "
            f"{row['frames']:4d}  substeps {row['substeps_mean']:8.0f}  compile "
            f"{row['compile_s']:6.1f} s  run {row['run_s_per_sim']:7.2f} s/sim  "
            f"(total {row['run_s_total']:7.1f} s)  speed-up x{row['speedup']:.0f} over "
            f"{row['reference_s_per_sim']:.0f} s  | min J {row['min_J']:.2f}  max pen "
            f"{100 * row['max_penetration_rel']:.2f} %  travel "
            f"{row['travel_clot_lengths_mean']:.1f} clot lengths",
            flush=True,
        )
    meta["load_avg_after"] = list(os.getloadavg())
    if args.json:
        out = Path(__file__).parent / "results" / f"solver_{device.platform}.json"
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({**meta, "results": rows}, indent=2) + "\n")
        print(f"wrote {out}")


if __name__ == "__main__":
    main()
