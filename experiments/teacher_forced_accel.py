"""Teacher-forced clot acceleration along the motion, per frame: a trained run against the truth.

    python experiments/teacher_forced_accel.py --run runs/bv --dataset data/bendvessel.h5 \
        --sims bendvessel_005,bendvessel_012

For every frame t of each simulation, the run's learned step predicts s_{t+1} from the true
frames; printed is the clot centroid's acceleration along its motion (s_t - s_{t-1} of the
centroid), true / predicted, in milli vessel radii per frame squared. A rollout that speeds
up from true-input predictions near the truth's zero is driven by the states it reaches, not
by the one step (``experiments/results/ladder_budget/bendvessel_histnoise/README.md``).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from thrombojax.data.radius import vessel_radius
from thrombojax.eval.single_step import batched_next, scaled_simulation
from thrombojax.io.hdf5 import open_dataset
from thrombojax.train.state import TrainedModel, load_trained
from thrombojax.types import clot_mask


def accelerations(trained: TrainedModel, dataset, name: str) -> list[tuple[int, float, float]]:
    """``(t, true, predicted)`` centroid accelerations along the motion, milli-radii / frame^2,
    of simulation ``name`` of an open dataset (each frame one call of the compiled step)."""
    r = vessel_radius(dataset) / float(trained.scaling.scale)
    step = trained.step
    step.require_dense("teacher-forced accelerations")
    pos, nt = scaled_simulation(dataset, name, trained.scaling)
    clot, mask = clot_mask(nt), np.ones(len(nt), bool)
    c = pos[:, clot].mean(axis=1)
    rows = []
    for t in range(step.history, pos.shape[0] - 1):
        nxt = np.asarray(batched_next(step, trained.params, trained.stats,
                                      step.previous(pos, t)[None], pos[t][None], nt, mask))[0]
        along = (c[t] - c[t - 1]) / np.linalg.norm(c[t] - c[t - 1])
        true = (c[t + 1] - 2 * c[t] + c[t - 1]) @ along / r
        pred = (nxt[clot].mean(axis=0) - 2 * c[t] + c[t - 1]) @ along / r
        rows.append((t, 1000 * float(true), 1000 * float(pred)))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--run", required=True, help="a trained run folder")
    parser.add_argument("--dataset", required=True, help="the dataset (.h5)")
    parser.add_argument("--sims", required=True, help="simulations (comma-separated)")
    args = parser.parse_args(argv)
    trained, dataset = load_trained(args.run), open_dataset(args.dataset)
    for name in args.sims.split(","):
        rows = accelerations(trained, dataset, name)
        print(f"{name} (t: true / predicted, milli-r per frame^2)")
        print(" ".join(f"{t}:{a:+.0f}/{p:+.0f}" for t, a, p in rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
