"""How the recorded ClotEntry rollouts miss: their final error along the true track, across it,
and the clot's size, over every row JSON already under a results folder. Nothing is rolled out.
Run from the repository root::

    python experiments/results/clot_speed/row_errors.py OUT.md ROOT [--sims A,B,...] [--force]

Every JSON under ROOT that ``bendvessel_shapes/cross_eval.py`` or the ladder wrote with a
per-step track (``along_per_step_r``, ``across_per_step_r``, ``size_ratio_per_step``) for one
of the simulations (default the ClotEntry held-out pair and its validation simulation) is
read; a row copied into another folder (the same final error to 1e-6 r) counts once. Rows
whose file name holds ``guards`` are guarded, the others alone. Per simulation and kind, the
table gives the number of rows, the share whose final centroid error is within 1 r, the
medians of the final error's two parts (``eval/track.py``: the arc length between the
predicted centroid's projection on the true track and the true centroid, and the distance
from the track) and the share of rows within 1 r for each part alone, and the medians of
the distance from the track and of the size ratio (the rolled-out clot's RMS radius about its
centroid over the true clot's) at a few steps.
"""

import argparse
import json
import pathlib
import sys

import numpy as np

from thrombojax.eval.tables import environment, markdown_table
from thrombojax.io.outputs import atomic_write_text, check_targets

STEPS = (40, 100, 140, 160)
DEFAULT_SIMS = ("clotentry_008", "clotentry_009", "clotentry_007")
FIELDS = ("final_centroid_r", "final_along_r", "final_across_r", "across_per_step_r",
          "size_ratio_per_step")


def collect(root: pathlib.Path, sims: list[str]) -> dict[tuple[str, str], list[dict]]:
    """``{(simulation, "guarded" | "alone"): [that simulation's record of each distinct row]}``."""
    found: dict[tuple[str, str], list[dict]] = {}
    seen: set[tuple[str, float]] = set()
    for path in sorted(root.rglob("*.json")):
        try:
            records = json.loads(path.read_text())["simulations"]
        except (KeyError, TypeError, ValueError):
            continue  # configs, metrics, tables: not a row
        if not isinstance(records, dict):
            continue
        for sim in sims:
            rec = records.get(sim)
            if not isinstance(rec, dict) or any(k not in rec for k in FIELDS):
                continue
            key = (sim, round(float(rec["final_centroid_r"]), 6))
            if key in seen:
                continue
            seen.add(key)
            kind = "guarded" if "guards" in path.name else "alone"
            found.setdefault((sim, kind), []).append(rec)
    return found


def row(sim: str, kind: str, recs: list[dict]) -> list:
    """One table row: counts, shares within 1 r and medians."""
    final = np.array([r["final_centroid_r"] for r in recs])
    along = np.abs([r["final_along_r"] for r in recs])
    across = np.abs([r["final_across_r"] for r in recs])
    at = {s: (np.median([abs(r["across_per_step_r"][s - 1]) for r in recs]),
              np.median([r["size_ratio_per_step"][s - 1] for r in recs]))
          for s in STEPS if all(len(r["across_per_step_r"]) >= s for r in recs)}
    return [sim, kind, len(recs), f"{np.mean(final < 1):.0%}", float(np.median(final)),
            float(np.median(along)), f"{np.mean(along < 1):.0%}", float(np.median(across)),
            f"{np.mean(across < 1):.0%}",
            " / ".join(f"{a:.2f}" for a, _ in at.values()),
            " / ".join(f"{s:.2f}" for _, s in at.values())]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=pathlib.Path, help="the Markdown table to write")
    parser.add_argument("root", type=pathlib.Path, help="folder scanned for row JSONs")
    parser.add_argument("--sims", default=",".join(DEFAULT_SIMS),
                        help="simulations, comma-separated (default: %(default)s)")
    parser.add_argument("--force", action="store_true", help="replace an existing OUT")
    args = parser.parse_args()
    check_targets([args.out], force=args.force)
    sims = [s for s in args.sims.split(",") if s]
    found = collect(args.root, sims)
    if not found:
        sys.exit(f"{args.root}: no row JSON holds a per-step track of {', '.join(sims)}")
    rows = [row(sim, kind, found[(sim, kind)]) for sim in sims for kind in ("guarded", "alone")
            if (sim, kind) in found]
    steps = " / ".join(str(s) for s in STEPS)
    table = markdown_table(
        ["simulation", "rows", "count", "final within 1 r", "final (median, r)",
         "along (median, r)", "along within 1 r", "across (median, r)", "across within 1 r",
         f"across at steps {steps} (median, r)", f"size ratio at steps {steps} (median)"],
        rows)
    env = environment()
    atomic_write_text(args.out, (
        f"# How the recorded ClotEntry rollouts miss (rows under `{args.root}`)\n\n{table}\n"
        + "".join(f"- {k}: {v}\n" for k, v in env.items())))
    print(table)


if __name__ == "__main__":
    main()
