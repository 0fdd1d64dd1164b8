"""Where each rolled-out clot is on its way, not only at the end, from the rows' JSONs alone.

    python experiments/results/ladder_budget/clotentry_rest/track.py OUT.md DIR [DIR ...]

For every row JSON that ``bendvessel_shapes/cross_eval.py`` wrote into each DIR (``ladder.json``
is skipped) and every simulation in it: the final centroid error, the largest centroid error
over the rollout and its step (``centroid_per_step_r``), and the clot's speed along its track,
model against truth, as means over four equal blocks of steps (``speed_per_step_r``,
``speed_true_per_step_r``; vessel radii per frame). A final error inside 1 r can hide a clot
that ran ahead early and fell behind late; the largest error over the way cannot. Nothing is
rolled out. Run from the repository root.
"""

import argparse
import json
import pathlib
import sys

import numpy as np

from thrombojax.eval.tables import environment
from thrombojax.io.outputs import atomic_write_text, refuse_targets

BLOCKS = 4


def block_means(values: list[float]) -> list[float]:
    """Means of ``values`` over ``BLOCKS`` equal consecutive blocks (the last takes the rest)."""
    parts = np.array_split(np.asarray(values, np.float64), BLOCKS)
    return [float(p.mean()) for p in parts]


def rows(folder: pathlib.Path) -> list[str]:
    """One table line per (row, simulation) of the row JSONs in ``folder``."""
    lines = []
    paths = sorted(p for p in folder.glob("*.json") if p.name != "ladder.json")
    if not paths:
        sys.exit(f"{folder}: no row JSONs (cross_eval.py's <label>.json) to read")
    for path in paths:
        result = json.loads(path.read_text())
        for name, sim in result["simulations"].items():
            try:
                track = np.asarray(sim["centroid_per_step_r"], np.float64)
                model, truth = sim["speed_per_step_r"], sim["speed_true_per_step_r"]
            except KeyError as err:
                sys.exit(f"{path}: simulation {name}: no field {err.args[0]!r}; measure the "
                         "row again with cross_eval.py")
            worst = int(np.argmax(track))
            speeds = " / ".join(f"{m:.3f} ({t:.3f})" for m, t in
                                zip(block_means(model), block_means(truth), strict=True))
            lines.append(f"| {folder.name} | {path.stem} | {name} | "
                         f"{sim['final_centroid_r']:.2f} | {track[worst]:.2f} (step {worst + 1}) "
                         f"| {speeds} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", help="the Markdown table to write")
    parser.add_argument("dirs", nargs="+", help="folders of cross_eval.py row JSONs")
    parser.add_argument("--force", action="store_true", help="replace an existing OUT")
    args = parser.parse_args()
    refuse_targets(parser, (args.out,), force=args.force, what="table")
    lines = [line for d in args.dirs for line in rows(pathlib.Path(d))]
    env = environment()
    text = "\n".join([
        "# Centroid error over the way and speed along the track (vessel radii)", "",
        f"Command: `python experiments/results/ladder_budget/clotentry_rest/track.py {args.out} "
        f"{' '.join(args.dirs)}`; date {env['date']}; device {env['device']}; load "
        f"{env['load_avg_1_5_15']}; python {env['python']}, numpy {np.__version__}, thrombojax "
        f"{env['thrombojax']}. Read from the row JSONs; nothing rolled out. Speeds: model (truth) "
        f"in r per frame, means over {BLOCKS} equal blocks of the rollout's steps.", "",
        "| folder | row | simulation | final centroid error | largest over the rollout | "
        "speed per block: model (truth) |",
        "|---|---|---|---|---|---|",
        *lines, ""])
    atomic_write_text(args.out, text)
    print(text)


if __name__ == "__main__":
    main()
