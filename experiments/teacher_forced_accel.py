"""Teacher-forced clot acceleration along the motion, per frame: a trained run against the truth.

    python experiments/teacher_forced_accel.py --run runs/bv --dataset data/bendvessel.h5 \
        --sims bendvessel_005,bendvessel_012

For every frame t of each simulation, the run's learned step predicts s_{t+1} from the true
frames; printed is the clot centroid's acceleration along its motion (s_t - s_{t-1} of the
centroid), true / predicted, in milli vessel radii per frame squared. A rollout that speeds
up from true-input predictions near the truth's zero is driven by the states it reaches, not
by the one step (``experiments/results/ladder_budget/bendvessel_histnoise/README.md``).

``--nodes N`` evaluates on the ladder's fixed subset of ``N`` nodes (``subsample_indices`` with
seed 0, as ``experiments/ladder_eval.py``: ClotEntry's 2,048), which models with vessel-axis or
wall features need on a full-resolution dataset; ``--which last`` loads the last checkpoint.
``--blocks B`` also prints, per block of ``B`` frames from the dataset's ``skip_frames``, the
mean true and predicted acceleration and their correlation over the frames: a step whose
clot-mean acceleration is biased in one direction moves its rollout's clot off the true one
by the integral of that bias.

With ``--on-rollout`` the run is also rolled out (guards off) from the dataset's
``skip_frames``, and per rollout frame printed are: how far the rollout's clot centroid is
ahead of the true one along the motion and off it sideways (radii), its speed and the truth's
(radii per frame), and the predicted acceleration along the motion (milli-r per frame squared)
from the rollout's own frames, from the true clot moved frame by frame onto the rollout's
centroid track (the true shape, the rollout's place and motion), from the true clot moved to
the rollout's place at t (the true shape and motion), and from the true frames themselves
(teacher-forced): which of the rollout's errors the step's acceleration answers to.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from thrombojax.data.augment import subsample_indices
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.single_step import batched_next, scaled_simulation
from thrombojax.io.hdf5 import open_dataset
from thrombojax.simulator.rollout import rollout_with_corrections
from thrombojax.study import skip_frames
from thrombojax.train.state import TrainedModel, load_trained
from thrombojax.types import clot_mask


def _simulation(trained: TrainedModel, dataset, name: str, nodes: int | None):
    """Scaled positions and node types of ``name``, on the ladder's subset of ``nodes``."""
    pos, nt = scaled_simulation(dataset, name, trained.scaling)
    if nodes:
        idx = subsample_indices(0, nt, nodes)
        pos, nt = pos[:, idx], nt[idx]
    return pos, nt


def accelerations(trained: TrainedModel, dataset, name: str,
                  nodes: int | None = None) -> list[tuple[int, float, float]]:
    """``(t, true, predicted)`` centroid accelerations along the motion, milli-radii / frame^2,
    of simulation ``name`` of an open dataset (each frame one call of the compiled step), on
    all nodes or the ladder's subset of ``nodes``."""
    r = vessel_radius(dataset) / float(trained.scaling.scale)
    step = trained.step
    step.require_dense("teacher-forced accelerations")
    pos, nt = _simulation(trained, dataset, name, nodes)
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
    parser.add_argument("--on-rollout", action="store_true",
                        help="also the step's acceleration on its own rollout's states")
    parser.add_argument("--nodes", type=int, default=None,
                        help="the ladder's fixed subset of this many nodes (default: all)")
    parser.add_argument("--which", choices=("best", "last"), default="best",
                        help="checkpoint to load (default best)")
    parser.add_argument("--blocks", type=int, default=0,
                        help="also a summary per block of this many frames (default 0: none)")
    args = parser.parse_args(argv)
    trained = load_trained(args.run, which=args.which)
    dataset = open_dataset(args.dataset)
    for name in args.sims.split(","):
        rows = accelerations(trained, dataset, name, args.nodes)
        print(f"{name} (t: true / predicted, milli-r per frame^2)")
        print(" ".join(f"{t}:{a:+.0f}/{p:+.0f}" for t, a, p in rows))
        if args.blocks:
            print(block_summary(rows, skip_frames(dataset), args.blocks))
        if args.on_rollout:
            print(f"{name} on its rollout: t | ahead, sideways (r) | speed rollout / true "
                  "(r/frame) | acceleration from the rollout / the true clot on its track / "
                  "the true clot at its place / the true frames (milli-r/frame^2)")
            for t, *vals in on_rollout(trained, dataset, name, args.nodes):
                print(f"{t:3d} | {vals[0]:+.2f} {vals[1]:.2f} | {vals[2]:.3f} / {vals[3]:.3f} | "
                      + " / ".join(f"{v:+.1f}" for v in vals[4:]))
    return 0


def block_summary(rows: list[tuple[int, float, float]], start: int, size: int) -> str:
    """Per block of ``size`` frames from ``start``: mean true and predicted acceleration
    (milli-r / frame^2) and their correlation; the last line over all frames from ``start``."""
    a = np.array(rows, float).reshape(-1, 3)
    a = a[a[:, 0] >= start]
    if not len(a):
        return f"  no frames from {start}"
    last = int(a[-1, 0])
    spans = [(lo, min(lo + size, last + 1) - 1) for lo in range(start, last + 1, size)]
    lines = []
    for lo, hi in spans + [(start, last)]:
        sel = a[(a[:, 0] >= lo) & (a[:, 0] <= hi)]
        corr = np.corrcoef(sel[:, 1], sel[:, 2])[0, 1] if len(sel) > 2 else float("nan")
        lines.append(f"  frames {lo}-{hi}: true {sel[:, 1].mean():+.2f}, predicted "
                     f"{sel[:, 2].mean():+.2f} milli-r/frame^2 (correlation {corr:+.2f})")
    return "\n".join(lines)


def on_rollout(trained: TrainedModel, dataset, name: str,
               nodes: int | None = None) -> list[tuple]:
    """Per rollout frame ``(t, ahead, sideways, speed, true speed, a_rollout, a_track, a_place,
    a_true)`` (module docstring; radii, radii per frame, milli-radii per frame squared)."""
    r = vessel_radius(dataset) / float(trained.scaling.scale)
    step = trained.step
    pos, nt = _simulation(trained, dataset, name, nodes)
    clot, mask = clot_mask(nt), np.ones(len(nt), bool)
    skip = max(skip_frames(dataset), step.history)
    pred, _ = rollout_with_corrections(step, trained.params, trained.stats,
                                       step.previous(pos, skip), pos[skip], nt, mask,
                                       pos.shape[0] - 1 - skip)
    roll = np.concatenate([pos[:skip + 1], np.asarray(pred)])  # frame index as the truth's
    prev_shape = np.shape(step.previous(pos, skip))  # [H, N, 3], or [N, 3] for H = 1

    def accel(windows):  # windows [B, H + 1, N, 3]: the inputs, s_t last; one call for all
        nxt = np.asarray(batched_next(step, trained.params, trained.stats,
                                      windows[:, :-1].reshape(len(windows), *prev_shape),
                                      windows[:, -1], nt, mask))
        c = windows[:, :, clot].mean(axis=2)
        along = (c[:, -1] - c[:, -2]) / np.linalg.norm(c[:, -1] - c[:, -2], axis=-1)[:, None]
        a = nxt[:, clot].mean(axis=1) - 2 * c[:, -1] + c[:, -2]
        return 1000 * np.sum(a * along, axis=-1) / r

    rows = []
    for t in range(skip + 1, pos.shape[0] - 1):
        true, mine = pos[t - step.history:t + 1], roll[t - step.history:t + 1]
        ct, cr = true[:, clot].mean(axis=1), mine[:, clot].mean(axis=1)
        track, place = true.copy(), true.copy()
        track[:, clot] += (cr - ct)[:, None]
        place[:, clot] += cr[-1] - ct[-1]
        u = (ct[-1] - ct[-2]) / np.linalg.norm(ct[-1] - ct[-2])
        off = cr[-1] - ct[-1]
        rows.append((t, float(off @ u) / r, float(np.linalg.norm(off - (off @ u) * u)) / r,
                     float(np.linalg.norm(cr[-1] - cr[-2])) / r,
                     float(np.linalg.norm(ct[-1] - ct[-2])) / r,
                     *map(float, accel(np.stack([mine, track, place, true])))))
    return rows


if __name__ == "__main__":
    sys.exit(main())
