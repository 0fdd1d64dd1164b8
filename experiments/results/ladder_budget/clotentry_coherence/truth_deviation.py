"""How far the true clot strays from a rigid copy of its rollout start: what the coherence
guard's tolerance would cut from the truth itself. No model. Run from the repository root::

    python experiments/results/ladder_budget/clotentry_coherence/truth_deviation.py OUT.md \\
        DATA [--tolerances 0.3,0.5,0.7,1.0] [--force]

For every simulation and every 4th frame of the rollout window (from the dataset's
``skip_frames``), each true clot node's distance from its place in the best rigid copy of the
clot at ``skip_frames`` (``thrombojax.eval.coherence_fit.clot_deviations``: the coherence
guard's correction at tolerance 0), in vessel radii, on all clot nodes. Per simulation: the
largest distance and the frame it occurs at, its 99th percentile over the nodes at the worst
frame, and for each tolerance the share of (node, frame) pairs beyond it: the nodes a guard at
that tolerance would move on the true clot.
"""

import argparse
import pathlib

import numpy as np

from thrombojax import study
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.coherence_fit import clot_deviations
from thrombojax.eval.tables import environment, markdown_table
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.types import NodeType

EVERY = 4


def deviations(positions: np.ndarray, start: int, r: float) -> np.ndarray:
    """``[frames, clot nodes]`` distances (radii) of the clot ``positions [T, C, 3]`` from the
    best rigid copy of frame ``start``, every ``EVERY``-th frame from ``start`` (the first row,
    frame ``start`` itself, zero)."""
    every = clot_deviations(positions, np.full(positions.shape[1], NodeType.CLOT), start, r)
    return np.concatenate([np.zeros_like(every[:1]), every[EVERY - 1::EVERY]])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=pathlib.Path, help="the Markdown table to write")
    parser.add_argument("data", help="HDF5 dataset")
    parser.add_argument("--tolerances", default="0.3,0.5,0.7,1.0",
                        help="coherence tolerances in radii (default: %(default)s)")
    parser.add_argument("--force", action="store_true", help="replace an existing OUT")
    args = parser.parse_args()
    check_targets([args.out], force=args.force)
    tolerances = [float(t) for t in args.tolerances.split(",")]
    ds = open_dataset(args.data)
    start, r = study.skip_frames(ds), vessel_radius(ds)
    rows = []
    for name in ds.names:
        clot = ds.node_type(name) == NodeType.CLOT
        dev = deviations(np.asarray(ds.positions(name))[:, clot], start, r)
        worst = int(dev.max(1).argmax())
        rows.append([name, float(dev.max()), start + EVERY * worst,
                     float(np.percentile(dev[worst], 99))]
                    + [f"{np.mean(dev > t):.2%}" for t in tolerances])
        print(" | ".join(str(v) for v in rows[-1]), flush=True)
    table = markdown_table(["simulation", "largest (r)", "at frame", "99th percentile there (r)"]
                           + [f"beyond {t:g} r" for t in tolerances], rows)
    atomic_write_text(args.out, (
        f"# The true clot against a rigid copy of frame {start} ({pathlib.Path(args.data).name}, "
        f"every {EVERY}th frame, all clot nodes)\n\n{table}\n"
        + "".join(f"- {k}: {v}\n" for k, v in environment().items())))


if __name__ == "__main__":
    main()
