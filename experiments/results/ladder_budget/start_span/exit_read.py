"""Does a step run each simulation's exit at its own speed? Teacher-forced, per simulation.

For each model and simulation, the step predicts the next frame from the true frames over the
clot's exit (the last ``EXIT`` frames of the record) and over the slide before it (the rollout's
start + 1 to ``EXIT + 2`` frames before the end). It reports, in vessel radii per frame, the
true and the predicted clot centroid speed in the exit and the exit's speed-up (exit speed minus
slide speed), then, over the simulations, how the predicted speed-up follows the true one: the
correlation and the least-squares slope (1: each simulation's exit as it is; 0: one exit for
all).

Run from the repository root::

    python experiments/results/ladder_budget/start_span/exit_read.py OUT.md DATA SIMS L=RUN ...

It writes (never over an existing OUT.md) and prints a Markdown table, each run's last
checkpoint, at most 2,048 nodes; then the date, command, device, versions, CPU and load
(:func:`thrombojax.eval.tables.measured_line`).
"""

from __future__ import annotations

import pathlib
import sys

import jax.numpy as jnp
import numpy as np

from thrombojax import study
from thrombojax.data.augment import subsample_indices
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.single_step import batched_next, scaled_simulation
from thrombojax.eval.tables import measured_line
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.train.state import load_trained
from thrombojax.types import clot_mask

EXIT = 6
"""Frames at the end of the record counted as the exit (BendVessel's clot leaves in its last
6-7 frames)."""


def speeds(tr, ds, name, start):
    """``(true, predicted)`` mean centroid speeds, r per frame, ``[2]`` each: slide, exit."""
    step, r = tr.step, vessel_radius(ds) / float(tr.scaling.scale)
    full, full_nt = scaled_simulation(ds, name, tr.scaling)
    idx = subsample_indices(0, full_nt, min(len(full_nt), 2048))
    pos, nt = full[:, idx], full_nt[idx]
    clot, last = clot_mask(nt), pos.shape[0] - 1
    frames = np.arange(start + 1, last)  # predict s_{t+1} from the true frames up to t
    prev = np.asarray(step.previous(pos, frames, start_from=start))  # [frames, ...] at once
    nxt = np.asarray(batched_next(step, tr.params, tr.stats, jnp.asarray(prev, jnp.float32),
                                  jnp.asarray(pos[frames]), jnp.asarray(nt),
                                  jnp.ones(len(nt), bool)))
    centre = pos[:, clot].mean(axis=1)
    true = np.linalg.norm(centre[frames + 1] - centre[frames], axis=1) / r
    pred = np.linalg.norm(nxt[:, clot].mean(axis=1) - centre[frames], axis=1) / r
    exit_ = frames + 1 > last - EXIT
    slide = frames + 1 <= last - EXIT - 2
    return (np.array([true[slide].mean(), true[exit_].mean()]),
            np.array([pred[slide].mean(), pred[exit_].mean()]))


def main(argv):
    out, data, sims, rows = pathlib.Path(argv[0]), argv[1], argv[2].split(","), argv[3:]
    check_targets([out], force=False)
    ds = open_dataset(data)
    start = max(study.skip_frames(ds), 1)
    lines = [f"Teacher-forced on {data}, rollout start frame {start}, the exit its last {EXIT} "
             "frames; speeds in vessel radii per frame.", "",
             "| model | simulation | true: slide / exit / speed-up | predicted: slide / exit / "
             "speed-up |", "|---|---|---|---|"]
    summary = ["", "| model | speed-up followed: correlation / slope | mean predicted / true "
               "speed-up |", "|---|---|---|"]
    for row in rows:
        label, run = row.split("=", 1)
        tr = load_trained(run, which="last")
        ups = []
        for name in sims:
            true, pred = speeds(tr, ds, name, start)
            ups.append((true[1] - true[0], pred[1] - pred[0]))
            lines.append(f"| {label} | {name} | {true[0]:.3f} / {true[1]:.3f} / "
                         f"{ups[-1][0]:+.3f} | {pred[0]:.3f} / {pred[1]:.3f} / "
                         f"{ups[-1][1]:+.3f} |")
            print(lines[-1], flush=True)
        u = np.array(ups)
        dev = u[:, 0] - u[:, 0].mean()
        slope = float(np.dot(dev, u[:, 1] - u[:, 1].mean()) / np.dot(dev, dev))
        summary.append(f"| {label} | {np.corrcoef(u[:, 0], u[:, 1])[0, 1]:.2f} / {slope:.2f} | "
                       f"{u[:, 1].mean():+.3f} / {u[:, 0].mean():+.3f} |")
    lines += summary + ["", measured_line()]
    atomic_write_text(out, "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1:])
