"""The same models on held-out and on training simulations: is ClotEntry's final error a gap
between seen and unseen vessels? Reads rows written by ``cross_eval.py`` (one ``LABEL.json``
per row, each with its per-simulation figures) from a held-out folder and a training folder,
and writes ``compare.md`` (atomically; an existing file only with ``--force``) with, per row
and simulation, the final centroid error, the error along the true clot's track (+: ahead),
the mean clot speed of the rollout and of the truth, the full-rollout MSE and the
rollout-phase single step against constant velocity (CV), and the mean over each set. No
model is run. From the repository root::

    python experiments/results/ladder_budget/clotentry_finetune/training_sims/compare.py \\
        HELD_OUT_DIR TRAINING_DIR OUT_DIR LABEL [LABEL ...] [--force]
"""

from __future__ import annotations

import argparse
import datetime
import json
import pathlib
import sys

import numpy as np

from thrombojax.io.outputs import atomic_write_text, check_targets


def rows(result: dict) -> list[tuple]:
    """(simulation, final r, along r, speed, true speed, MSE@full / CV, 1-step / CV) each."""
    out = []
    for name, s in result["simulations"].items():
        out.append((name, s["final_centroid_r"], s["final_along_r"],
                    float(np.mean(s["speed_per_step_r"])),
                    float(np.mean(s["speed_true_per_step_r"])),
                    s["mse_full"] / s["mse_full_cv"], s["mse1_phase"] / s["mse1_phase_cv"]))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("held_out", help="folder of the held-out rows (LABEL.json)")
    parser.add_argument("training", help="folder of the training-simulation rows (LABEL.json)")
    parser.add_argument("out", help="folder compare.md is written into")
    parser.add_argument("labels", nargs="+", help="rows present in both folders")
    parser.add_argument("--force", action="store_true", help="replace an existing compare.md")
    args = parser.parse_args(argv)
    target = pathlib.Path(args.out) / "compare.md"
    check_targets([target], force=args.force)
    lines = ["# Held-out against training simulations, per row and simulation", "",
             "| row | set | simulation | final centroid (r) | along the track (r, +: ahead) | "
             "rollout speed (r / frame) | true speed | MSE@full / CV | 1-step / CV "
             "(rollout phase) |", "|---|---|---|---|---|---|---|---|---|"]
    for label in args.labels:
        for kind, folder in (("held out", args.held_out), ("training", args.training)):
            result = json.loads((pathlib.Path(folder) / f"{label}.json").read_text())
            got = rows(result)
            for name, fin, along, sp, st, full, one in got:
                lines.append(f"| {label} | {kind} | {name} | {fin:.2f} | {along:+.2f} | "
                             f"{sp:.3f} | {st:.3f} | {full:.3f} | {one:.2f} |")
            mean = np.mean([g[1:] for g in got], axis=0)
            lines.append(f"| {label} | {kind} | **mean** | **{mean[0]:.2f}** | "
                         f"{np.mean([abs(g[2]) for g in got]):.2f} | {mean[2]:.3f} "
                         f"| {mean[3]:.3f} | {mean[4]:.3f} | {mean[5]:.2f} |")
    lines += ["", f"- date: {datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')}",
              "- command: python " + " ".join([pathlib.Path(sys.argv[0]).name, *sys.argv[1:]]),
              "- no model run: every figure is read from the rows' JSON",
              "- **mean** rows: the mean over the set's simulations (of the ratios too, so they "
              "can differ from `table.md`, whose ratios are of the means); along the track: "
              "the mean of its absolute values"]
    atomic_write_text(target, "\n".join(lines) + "\n")
    print(target)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
