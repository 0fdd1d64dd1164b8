"""The true clot's speed on each ClotEntry simulation, by blocks of frames, from the data alone.

    python experiments/results/ladder_budget/clotentry_skip/speeds.py data/clotentry.h5 OUT.md

Speed: the distance the clot centroid moves per frame (``centroid_speed`` of
``experiments/clot_speed.py``), in vessel radii (``thrombojax.data.radius.vessel_radius``),
averaged over each block of frames. Frames before the dataset's ``skip_frames`` are where the
clot enters and starts from rest. Run from the repository root.
"""

import argparse
import sys

import h5py
import numpy as np

sys.path.insert(0, "experiments")
from clot_speed import centroid_speed  # noqa: E402

from thrombojax import study  # noqa: E402
from thrombojax.data.radius import vessel_radius  # noqa: E402
from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.io.hdf5 import open_dataset  # noqa: E402
from thrombojax.io.outputs import atomic_write_text, refuse_targets  # noqa: E402
from thrombojax.types import clot_mask  # noqa: E402

BLOCKS = ((1, 10), (10, 20), (20, 40), (40, 80), (80, 120), (120, 160), (160, 200))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset")
    parser.add_argument("out")
    parser.add_argument("--force", action="store_true", help="replace an existing OUT")
    args = parser.parse_args()
    refuse_targets(parser, (args.out,), force=args.force, inputs=(args.dataset,), what="table")
    ds = open_dataset(args.dataset)
    skip, r = study.skip_frames(ds), vessel_radius(ds)
    rows = []
    for name in ds.names:
        _, speed = centroid_speed(np.asarray(ds.positions(name)),
                                  clot_mask(np.asarray(ds.node_type(name))))
        speed = speed / r  # speed[t]: frame t -> t + 1
        rows.append((name, [speed[a:b].mean() for a, b in BLOCKS], speed[skip:].mean()))
    env = environment()
    lines = [f"# The true clot's speed on {args.dataset} (vessel radii per frame)", "",
             f"Command: `python experiments/results/ladder_budget/clotentry_skip/speeds.py "
             f"{args.dataset} {args.out}`; date {env['date']}; device {env['device']}; "
             f"load {env['load_avg_1_5_15']}; python {env['python']}, numpy {np.__version__}, "
             f"h5py {h5py.__version__}, thrombojax {env['thrombojax']}. Rollouts start at frame "
             f"{skip} (the dataset's skip_frames).", "",
             "| simulation | " + " | ".join(f"frames {a}-{b}" for a, b in BLOCKS)
             + f" | frames {skip}-end |",
             "|---|" + "---|" * (len(BLOCKS) + 1)]
    for name, blocks, after in rows:
        lines.append(f"| {name} | " + " | ".join(f"{v:.3f}" for v in blocks) + f" | {after:.3f} |")
    atomic_write_text(args.out, "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
