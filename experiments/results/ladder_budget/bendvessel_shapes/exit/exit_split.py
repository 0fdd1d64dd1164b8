"""Where along the vessel a rollout's final centroid error comes from: before the clot's exit,
or in it.

The true clot slides at an almost constant speed and then, over its last 4-7 frames, speeds up
to 2-2.7 times that as it passes the outlet's flare. Each evaluation row of ``../cross_eval.py``
(``OUT/<label>.json``) records per step the rollout's centroid error along the true clot's
track (``along_per_step_r``, > 0 ahead) and the true clot's speed (``speed_true_per_step_r``). This
splits the final error along the track at the first step whose true speed exceeds 1.15 times
the simulation's median: the error reached before the exit (``before``) and what the exit adds
(``exit``); ``final = before + exit``. Means over each row's simulations, in vessel radii.

Run from the repository root (prints a Markdown table; ``--json FILE`` also writes it)::

    python experiments/results/ladder_budget/bendvessel_shapes/exit/exit_split.py \\
        "held-out shapes=/work/exp/bv_shapes/cross_on_shapes" \\
        "longer vessel=/work/exp/bv_shapes/cross_on_long" --labels tscale_frame_s0,tscale_frame_s1
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

EXIT_SPEEDUP = 1.15


def split_row(row: dict) -> dict:
    """Mean ``before``, ``exit``, ``final`` along-track error and exit frames of one row."""
    before, exit_, frames = [], [], []
    for sim in row["simulations"].values():
        speed = np.asarray(sim["speed_true_per_step_r"])
        along = np.asarray(sim["along_per_step_r"])
        k = int(np.argmax(speed > EXIT_SPEEDUP * np.median(speed)))
        if k == 0:
            raise ValueError("exit split: the true clot never speeds up (or does at once)")
        before.append(along[k - 1])
        exit_.append(along[-1] - along[k - 1])
        frames.append(len(speed) - k)
    return {"before_r": float(np.mean(before)), "exit_r": float(np.mean(exit_)),
            "final_along_r": float(np.mean(before) + np.mean(exit_)),
            "exit_frames": frames}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sets", nargs="+", help="NAME=FOLDER: a test set and its cross_eval folder")
    ap.add_argument("--labels", required=True, help="comma-separated row labels")
    ap.add_argument("--json", type=pathlib.Path, help="also write the split here (not replaced)")
    args = ap.parse_args()
    sets = dict(s.split("=", 1) for s in args.sets)
    labels = args.labels.split(",")
    out: dict[str, dict] = {}
    print("| model | " + " | ".join(f"{n}: before / exit / final" for n in sets) + " |")
    print("|---|" + "---|" * len(sets))
    for label in labels:
        cells = []
        for name, folder in sets.items():
            path = pathlib.Path(folder) / f"{label}.json"
            if not path.exists():
                cells.append("-")
                continue
            s = split_row(json.loads(path.read_text()))
            out.setdefault(label, {})[name] = s
            cells.append(f"{s['before_r']:+.2f} / {s['exit_r']:+.2f} / {s['final_along_r']:+.2f}")
        print(f"| {label} | " + " | ".join(cells) + " |")
    if args.json:
        if args.json.exists():
            raise SystemExit(f"{args.json}: exists; not replaced")
        tmp = args.json.with_suffix(".tmp")
        meta = {"command": " ".join(["python", *sys.argv]),
                "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                "python": platform.python_version(), "numpy": np.__version__,
                "load": os.getloadavg()[0], "note": "from the evaluation rows' per-step "
                "records; each row's environment is in its ladder.json"}
        tmp.write_text(json.dumps({**meta, "sets": sets, "rows": out}, indent=1))
        tmp.replace(args.json)


if __name__ == "__main__":
    main()
