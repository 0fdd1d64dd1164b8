"""How much of a guarded ensemble's mean clot is outside the vessel, by both open-end tests.

``fraction_outside`` (``thrombojax/eval/metrics.py``) excuses clot nodes past an open end of
the vessel. With wall triangles it now decides "past an open end" as the rollout's guards do
(the nearest point of the wall mesh lies on an open edge or rim vertex); before 2026-11-30 it
used the nearest wall node's rim direction (the per-node test, still used without triangles).
This script rolls the guarded ensemble of the given runs out (last checkpoints, the ladder's
fixed node subset) and writes, per simulation, the largest fraction outside and the steps at
which any node is outside, by both tests, for the ensemble's mean and the truth. Run from the
repository root::

    python experiments/results/ladder_budget/clotentry_finetune/outside/outside.py OUT.md \\
        DATA NAME1,NAME2 RUN1 RUN2 ... [--nodes 2048]

OUT.md and OUT.json (the same figures and the environment) are written atomically; an
existing OUT.md is refused.
"""

import argparse
import json
import pathlib

import numpy as np

from thrombojax import study
from thrombojax.data.augment import subsample_indices
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.metrics import VesselWall, fit_vessel_wall, fraction_outside
from thrombojax.eval.single_step import scaled_simulation
from thrombojax.eval.tables import environment
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text
from thrombojax.simulator.ensemble import ensemble_rollout, stack_params
from thrombojax.simulator.guard_set import build_guards
from thrombojax.simulator.rollout import guarded_unroll
from thrombojax.train.state import load_trained
from thrombojax.types import clot_mask


def _outside(wall: VesselWall, traj: np.ndarray, clot: np.ndarray) -> dict:
    frac = fraction_outside(wall, traj, clot)
    return {"max_percent": round(100 * float(frac.max()), 3),
            "steps": [int(t) + 1 for t in np.nonzero(frac)[0]]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=pathlib.Path, help="the markdown file (and .json beside it)")
    ap.add_argument("data", help="the dataset (.h5)")
    ap.add_argument("names", help="simulations, comma-separated")
    ap.add_argument("runs", nargs="+", help="the ensemble's run directories")
    ap.add_argument("--nodes", type=int, default=2048, help="the ladder's node subset")
    args = ap.parse_args()
    if args.out.exists():
        raise SystemExit(f"{args.out} exists; move it away first")
    members = [load_trained(pathlib.Path(r), which="last") for r in args.runs]
    first = members[0]
    ds = open_dataset(args.data)
    skip = max(study.skip_frames(ds), 1)
    r = vessel_radius(ds) / float(first.scaling.scale)
    rows = {}
    for name in args.names.split(","):
        full, full_nt = scaled_simulation(ds, name, first.scaling)
        idx = subsample_indices(0, full_nt, args.nodes)
        pos, nt = full[:, idx], full_nt[idx]
        guards = build_guards(full[0], full_nt, pos[skip], nt, radius=r,
                              wall_cells=ds[name].wall_cells)
        ens = ensemble_rollout(first.step, stack_params([m.params for m in members]), first.stats,
                               first.step.previous(pos, skip), pos[skip], nt,
                               np.ones(len(nt), bool), pos.shape[0] - 1 - skip,
                               rollout_fn=guarded_unroll, context=guards, guard_mean=True)
        mesh = fit_vessel_wall(full[0], full_nt, wall_cells=ds[name].wall_cells)
        per_node = VesselWall(points=mesh.points, normals=mesh.normals, rim_dir=mesh.rim_dir,
                              spacing=mesh.spacing)
        clot, truth = clot_mask(nt), pos[skip + 1:]
        rows[name] = {test: {"ensemble mean": _outside(w, np.asarray(ens.mean), clot),
                             "truth": _outside(w, truth, clot)}
                      for test, w in (("mesh test", mesh), ("per-node test", per_node))}
    lines = ["| simulation | trajectory | max % outside, mesh test (steps) "
             "| max % outside, per-node test (steps) |", "|---|---|---|---|"]
    for name, tests in rows.items():
        for who in ("ensemble mean", "truth"):
            cells = [f"{tests[t][who]['max_percent']} ({tests[t][who]['steps'] or '-'})"
                     for t in ("mesh test", "per-node test")]
            lines.append(f"| {name} | {who} | {cells[0]} | {cells[1]} |")
    env = environment()
    lines += ["", f"Runs: {', '.join(args.runs)}; {args.nodes} nodes; guarded ensemble, "
              "last checkpoints.", "", "```", *(f"# {k}: {v}" for k, v in env.items()), "```"]
    atomic_write_text(args.out.with_suffix(".json"),
                      json.dumps({"rows": rows, "runs": args.runs, "measured": env}, indent=1))
    atomic_write_text(args.out, "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
