"""How much a step reads the clot's start speed, teacher-forced: its gain and the speed carry.

For each model (``--start-speed`` or not) and each rollout-phase frame t of the given
simulations, the step's next clot centroid is predicted from the true frames; then

* start-speed gain: with the two start frames (``s_{c-1}, s_c``, ``c`` = the dataset's rollout
  start) moved so that the clot's start speed reads 10 % faster, the share of that 10 % the
  predicted centroid motion takes on (1: the step runs at the start speed it is shown; 0: it
  ignores it; ``-`` for a step without it);
* speed carry: with the input motion (the frames before s_t) 5 % faster and the start frames
  true, the share the prediction keeps (:func:`thrombojax.eval.drift.speed_carry`).

Run from the repository root::

    python experiments/results/ladder_budget/start_speed/start_gain.py OUT.md DATA SIMS L=RUN ...

It writes (never over an existing OUT.md) and prints a Markdown table: the means over the
rollout phase's frames before the exit (the rollout's start + 1 to 8 frames before the end) and
the simulations, each run's last checkpoint, at most 2,048 nodes; then the date, command,
versions, CPU and load.
"""

from __future__ import annotations

import datetime
import os
import pathlib
import platform
import sys

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax import study
from thrombojax.data.augment import subsample_indices
from thrombojax.eval.drift import speed_carry
from thrombojax.eval.single_step import batched_next, scaled_simulation
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.train.state import load_trained
from thrombojax.types import NodeType


def start_gain(step, params, stats, pos, nt, start, frames, factor=0.1):
    """The mean share of a ``factor`` faster start speed the predicted centroid motion takes on."""
    clot = nt == NodeType.CLOT
    mask = np.ones(len(nt), bool)
    out = []
    for t in frames:
        prev = np.asarray(step.previous(pos, t, start_from=start), np.float32)
        lead = int(step.rest_edges)
        faster = prev.copy()  # s_{c-1} moved back: the start speed reads 1 + factor
        faster[lead] = prev[lead + 1] - (1 + factor) * (prev[lead + 1] - prev[lead])
        nxt = np.asarray(batched_next(step, params, stats, jnp.asarray(np.stack([prev, faster])),
                                      jnp.asarray(np.stack([pos[t], pos[t]])),
                                      jnp.asarray(nt), jnp.asarray(mask)), np.float64)
        base, pert = nxt[:, clot].mean(axis=1)
        v = base - pos[t, clot].mean(axis=0)
        speed = np.linalg.norm((prev[lead + 1] - prev[lead])[clot].mean(axis=0))
        out.append(float(np.dot(pert - base, v / np.linalg.norm(v))) / (factor * speed))
    return float(np.mean(out))


def main(argv):
    out, data, sims, rows = pathlib.Path(argv[0]), argv[1], argv[2].split(","), argv[3:]
    check_targets([out], force=False)
    ds = open_dataset(data)
    start = max(study.skip_frames(ds), 1)
    lines = [f"Teacher-forced on {', '.join(sims)} ({data}), rollout start frame {start}.", "",
             "| model | start-speed gain | speed carry |", "|---|---|---|"]
    for row in rows:
        label, run = row.split("=", 1)
        tr = load_trained(run, which="last")
        gains, carries = [], []
        for name in sims:
            full, full_nt = scaled_simulation(ds, name, tr.scaling)
            idx = subsample_indices(0, full_nt, min(len(full_nt), 2048))
            pos, nt = full[:, idx], full_nt[idx]
            frames = np.arange(start + 1, pos.shape[0] - 8)  # the rollout phase before the exit
            if tr.step.start_speed:
                gains.append(start_gain(tr.step, tr.params, tr.stats, pos, nt, start, frames))
            carries.append(float(np.mean(speed_carry(tr.step, tr.params, tr.stats, pos, nt,
                                                     frames, delta=0.05))))
        gain = f"{np.mean(gains):.3f}" if gains else "-"
        lines.append(f"| {label} | {gain} | {np.mean(carries):.3f} |")
    cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo")
                if ln.startswith("model name")), platform.processor())
    stamp = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    lines += ["", f"Command: python {' '.join(sys.argv)}; {stamp}; {cpu}, {os.cpu_count()} "
              f"cores, load {os.getloadavg()[0]:.1f}; Python {platform.python_version()}, jax "
              f"{jax.__version__}, numpy {np.__version__}."]
    atomic_write_text(out, "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1:])
