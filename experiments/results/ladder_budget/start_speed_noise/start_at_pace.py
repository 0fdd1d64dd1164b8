"""How much of a start-speed model's ClotEntry error its start speed makes: an oracle rollout.

Each run (trained with ``--start-speed``) is rolled out, guarded, on each simulation twice from
the same true frames: with its start frames as they are, and with ``s_c`` moved so that the start
speed reads the simulation's true mean speed over the rollout (its pace, which no rollout
knows). The final centroid error of each, in vessel radii.

Run from the repository root::

    python experiments/results/ladder_budget/start_speed_noise/start_at_pace.py OUT.md DATA \\
        SIMS TOLERANCE_R LABEL=RUN ...

It writes (never over an existing OUT.md) and prints a Markdown table, each run's last
checkpoint, at most 2,048 nodes, coherence at ``TOLERANCE_R`` vessel radii; then the date,
command, device, versions, CPU and load (:func:`thrombojax.eval.tables.measured_line`).
"""

from __future__ import annotations

import pathlib
import sys

import numpy as np

from thrombojax import study
from thrombojax.data.augment import subsample_indices
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.metrics import centroid_error
from thrombojax.eval.single_step import scaled_simulation
from thrombojax.eval.tables import measured_line
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.simulator.guard_set import build_guards
from thrombojax.simulator.rollout import rollout_with_corrections
from thrombojax.simulator.start_speed import scale_start_speed
from thrombojax.train.state import load_trained
from thrombojax.types import clot_mask


def final_errors(tr, ds, name, start, tolerance_r):
    """``(start speed, pace, final error with the true start, final error at the pace)``, r."""
    step = tr.step
    r = vessel_radius(ds) / float(tr.scaling.scale)
    full, full_nt = scaled_simulation(ds, name, tr.scaling)
    idx = subsample_indices(0, full_nt, min(len(full_nt), 2048))
    pos, nt = full[:, idx], full_nt[idx]
    n, mask, clot = pos.shape[0] - 1 - start, np.ones(len(nt), bool), clot_mask(nt)
    guards = build_guards(full[0], full_nt, pos[start], nt, radius=r,
                          wall_cells=ds[name].wall_cells, tolerance_r=tolerance_r)
    speed = np.linalg.norm(np.diff(pos[:, clot].mean(axis=1), axis=0), axis=1)
    out = []
    for factor in (1.0, speed[start:].mean() / speed[start - 1]):
        prev = scale_start_speed(step.previous(pos, start), factor, rest=step.rest_edges)
        pred, _ = rollout_with_corrections(step, tr.params, tr.stats, prev, pos[start], nt, mask,
                                           n, guards=guards)
        out.append(float(centroid_error(np.asarray(pred), pos[start + 1:], clot)[-1]) / r)
    return speed[start - 1] / r, speed[start:].mean() / r, out[0], out[1]


def main(argv):
    out, data, sims, tol, rows = (pathlib.Path(argv[0]), argv[1], argv[2].split(","),
                                  float(argv[3]), argv[4:])
    check_targets([out], force=False)
    ds = open_dataset(data)
    start = max(study.skip_frames(ds), 1)
    lines = [f"Guarded (coherence {tol:g} r), {data}, rollout start frame {start}; final "
             "centroid error with the true start frames and with the start speed at the pace.",
             "", "| model | simulation | start speed (r / frame) | pace (r / frame) | "
             "final error, true start (r) | final error, start at the pace (r) |",
             "|---|---|---|---|---|---|"]
    for row in rows:
        label, run = row.split("=", 1)
        tr = load_trained(run, which="last")
        if not tr.step.start_speed:
            raise SystemExit(f"{run}: not trained with --start-speed")
        for name in sims:
            s, p, true, paced = final_errors(tr, ds, name, start, tol)
            lines.append(f"| {label} | {name} | {s:.3f} | {p:.3f} | {true:.2f} | {paced:.2f} |")
            print(lines[-1], flush=True)
    lines += ["", measured_line()]
    atomic_write_text(out, "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1:])
