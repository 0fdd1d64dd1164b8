"""The final centroid error beside the way there: reads ``cross_eval.py``'s rows
(``FOLDER/<label>.json``) and writes one Markdown table with, per row (means over its
simulations, vessel radii): the one step against constant velocity in the rollout phase, the
speed carry of a single model (``thrombojax.eval.drift.speed_carry``: 1 keeps a speed error,
0 pulls it back in one step; none for an ensemble), the largest centroid error over the
rollout, the final one, and the final error along the true track split at the clot's exit
(``../bendvessel_shapes/exit/exit_split.py``: the error reached before the true clot speeds
up, and what the exit adds; + ahead). No model is run; the table is written atomically and
replaced only with ``--force``::

    python track_table.py --out track.md FOLDER LABEL[,LABEL...] [FOLDER LABELS ...]
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import pathlib
import platform
import sys

import numpy as np

from thrombojax.io.outputs import atomic_write_text, check_targets

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "bendvessel_shapes" / "exit"))
from exit_split import split_row  # noqa: E402

HEADER = ("| rows | model | 1-step / CV (rollout phase) | speed carry | largest centroid error "
          "(r) | final centroid error (r) | along the track: before the exit / in it / final "
          "(r) | max clot outside |\n|---|---|---|---|---|---|---|---|")


def row(folder: pathlib.Path, label: str) -> str:
    """One table row of the evaluation row ``folder/label.json``."""
    result = json.loads((folder / f"{label}.json").read_text())
    sims = result["simulations"].values()
    largest = np.mean([np.max(s["centroid_per_step_r"]) for s in sims])
    m = result["mean"]
    carry = f"{m['speed_carry']:.2f}" if "speed_carry" in m else "-"  # not for ensembles
    one_step = m["mse1_phase"] / m["mse1_phase_cv"]
    split = split_row(result)
    return (f"| {folder.name} | {label} | {one_step:.2f} | {carry} | {largest:.2f} | "
            f"{m['final_centroid_r']:.2f} | {split['before_r']:+.2f} / {split['exit_r']:+.2f} / "
            f"{split['final_along_r']:+.2f} | {100 * m['max_outside']:.1f} % |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pairs", nargs="+", help="FOLDER LABEL[,LABEL...] pairs")
    ap.add_argument("--out", type=pathlib.Path, required=True)
    ap.add_argument("--force", action="store_true", help="replace an existing --out")
    args = ap.parse_args()
    if len(args.pairs) % 2:
        ap.error("give FOLDER LABELS pairs")
    check_targets([args.out], force=args.force)
    lines = [HEADER]
    for folder, labels in zip(args.pairs[::2], args.pairs[1::2], strict=True):
        lines += [row(pathlib.Path(folder), label) for label in labels.split(",")]
    stamp = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    lines.append(f"\nFrom the rows' per-step records (no model run). Command: python "
                 f"{' '.join(sys.argv)}; {stamp}; Python {platform.python_version()}, numpy "
                 f"{np.__version__}; load {os.getloadavg()[0]:.1f}; each row's device and "
                 "versions are in its folder's ladder.json.")
    atomic_write_text(args.out, "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
