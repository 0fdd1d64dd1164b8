"""Where each rolled-out clot is on its way, not only at the end, from the rows' JSONs alone.

    python experiments/results/ladder_budget/clotentry_rest/track.py OUT.md DIR [DIR ...] \
        [--scan ROOT --sim NAME]

For every row JSON that ``bendvessel_shapes/cross_eval.py`` wrote into each DIR (``ladder.json``
is skipped) and every simulation in it: the final centroid error, the largest centroid error
over the rollout and its step (``centroid_per_step_r``), and the clot's speed along its track,
model against truth, as means over four equal blocks of steps (``speed_per_step_r``,
``speed_true_per_step_r``; vessel radii per frame). A final error inside 1 r can hide a clot
that ran ahead early and fell behind late; the largest error over the way cannot. With
``--scan ROOT --sim NAME`` a second table ranks every JSON under ROOT that holds simulation NAME
with a per-step centroid error (any results folder's rows; a copied row counted once) by that
largest error. Nothing is rolled out. Run from the repository root.
"""

import argparse
import json
import pathlib
import sys

import numpy as np

from thrombojax.eval.tables import environment
from thrombojax.io.outputs import atomic_write_text, refuse_targets

BLOCKS = 4
SHOWN = 10


def block_means(values: list[float]) -> list[float]:
    """Means of ``values`` over ``BLOCKS`` consecutive blocks (``np.array_split``: equal, or
    the first ones a step longer)."""
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
        if not isinstance(result, dict) or not isinstance(result.get("simulations"), dict):
            sys.exit(f"{path}: not a cross_eval.py row (no 'simulations'); keep only row JSONs "
                     "in the folder")
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
            lines.append(f"| {folder.parent.name}/{folder.name} | {path.stem} | {name} | "
                         f"{sim['final_centroid_r']:.2f} | {track[worst]:.2f} (step {worst + 1}) "
                         f"| {speeds} |")
    return lines


def scan(root: pathlib.Path, sim: str) -> list[str]:
    """Every JSON under ``root`` with ``simulations[sim].centroid_per_step_r``, ranked by its
    largest centroid error over the rollout: a count line and the ``SHOWN`` smallest."""
    found, seen = [], set()
    for path in sorted(root.rglob("*.json")):
        try:
            track = json.loads(path.read_text())["simulations"][sim]["centroid_per_step_r"]
        except (KeyError, TypeError, ValueError):
            continue  # not a row JSON of this simulation (configs, metrics, other tables)
        if tuple(track) in seen:
            continue  # a row copied into another folder (a control beside new rows)
        seen.add(tuple(track))
        track = np.asarray(track, np.float64)
        found.append((float(track.max()), int(np.argmax(track)) + 1, float(track[-1]), path))
    if not found:
        sys.exit(f"{root}: no JSON holds a per-step centroid error of simulation {sim!r}")
    found.sort(key=lambda item: item[0])
    line = "| `{3}` | {0:.2f} (step {1}) | {2:.2f} |".format
    near = [item for item in found if item[2] <= 1.0]
    return [f"{len(found)} distinct rows under `{root}` hold `{sim}`; the {min(SHOWN, len(found))} "
            "whose largest centroid error over the rollout is smallest:", "",
            "| row JSON | largest over the rollout | final centroid error |", "|---|---|---|",
            *(line(*item) for item in found[:SHOWN]), "",
            f"The {len(near)} of them that end within 1 r:", "",
            "| row JSON | largest over the rollout | final centroid error |", "|---|---|---|",
            *(line(*item) for item in sorted(near, key=lambda item: item[2]))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", help="the Markdown table to write")
    parser.add_argument("dirs", nargs="+", help="folders of cross_eval.py row JSONs")
    parser.add_argument("--scan", type=pathlib.Path, help="also rank every row JSON under it")
    parser.add_argument("--sim", help="with --scan: the simulation to rank the rows on")
    parser.add_argument("--force", action="store_true", help="replace an existing OUT")
    args = parser.parse_args()
    if (args.scan is None) != (args.sim is None):
        parser.error("--scan and --sim go together")
    refuse_targets(parser, (args.out,), force=args.force, what="table")
    lines = [line for d in args.dirs for line in rows(pathlib.Path(d))]
    ranked = scan(args.scan, args.sim) if args.scan else []
    env = environment()
    command = " ".join(["python experiments/results/ladder_budget/clotentry_rest/track.py",
                        args.out, *args.dirs,
                        *(["--scan", str(args.scan), "--sim", args.sim] if args.scan else [])])
    text = "\n".join([
        "# Centroid error over the way and speed along the track (vessel radii)", "",
        f"Command: `{command}`; date {env['date']}; device {env['device']}; load "
        f"{env['load_avg_1_5_15']}; python {env['python']}, numpy {np.__version__}, thrombojax "
        f"{env['thrombojax']}. Read from the row JSONs; nothing rolled out. Speeds: model (truth) "
        f"in r per frame, means over {BLOCKS} equal blocks of the rollout's steps.", "",
        "| folder | row | simulation | final centroid error | largest over the rollout | "
        "speed per block: model (truth) |",
        "|---|---|---|---|---|---|",
        *lines, "", *ranked, ""])
    atomic_write_text(args.out, text)
    print(text)


if __name__ == "__main__":
    main()
