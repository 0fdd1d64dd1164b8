"""The true clot's speed on each ClotEntry simulation, by blocks of frames, from the data alone.

    python experiments/results/ladder_budget/clotentry_skip/speeds.py data/clotentry.h5 OUT.md

Speed: the distance the centroid of the clot nodes (node type CLOT) moves per frame, in the
dataset's units (vessel radii, its ``units`` attribute), averaged over each block of frames.
Frames before the dataset's ``skip_frames`` are where the clot enters and starts from rest.
"""

import argparse

import h5py
import numpy as np

from thrombojax.eval.tables import environment
from thrombojax.io.outputs import atomic_write_text, refuse_targets
from thrombojax.types import NodeType

BLOCKS = ((1, 10), (10, 20), (20, 40), (40, 80), (80, 120), (120, 160), (160, 200))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset")
    parser.add_argument("out")
    parser.add_argument("--force", action="store_true", help="replace an existing OUT")
    args = parser.parse_args()
    refuse_targets(parser, (args.out,), force=args.force, inputs=(args.dataset,), what="table")
    with h5py.File(args.dataset, "r") as f:
        skip, units = int(f.attrs.get("skip_frames", 0)), f.attrs.get("units", "?")
        rows = []
        for name in sorted(f["simulations"]):
            g = f["simulations"][name]
            clot = np.flatnonzero(g["node_type"][:] == NodeType.CLOT)
            centroid = g["positions"][:, clot, :].mean(axis=1)
            speed = np.linalg.norm(np.diff(centroid, axis=0), axis=1)  # speed[t]: frame t -> t+1
            rows.append((name, [speed[a:b].mean() for a, b in BLOCKS],
                         speed[skip:].mean()))
    env = environment()
    lines = [f"# The true clot's speed on {args.dataset} ({units} per frame)", "",
             f"Command: `python experiments/results/ladder_budget/clotentry_skip/speeds.py "
             f"{args.dataset} {args.out}`; date {env['date']}; device {env['device']}; "
             f"load {env['load_avg_1_5_15']}; python {env['python']}, numpy {np.__version__}, "
             f"h5py {h5py.__version__}, thrombojax {env['thrombojax']}. Rollouts start at frame "
             f"{skip} "
             "(the dataset's skip_frames).", "",
             "| simulation | " + " | ".join(f"frames {a}-{b}" for a, b in BLOCKS)
             + f" | frames {skip}-end |",
             "|---|" + "---|" * (len(BLOCKS) + 1)]
    for name, blocks, after in rows:
        lines.append(f"| {name} | " + " | ".join(f"{v:.3f}" for v in blocks) + f" | {after:.3f} |")
    atomic_write_text(args.out, "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
