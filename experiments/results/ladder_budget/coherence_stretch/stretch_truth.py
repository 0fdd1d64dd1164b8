"""How far BendVessel's true clots lie from the coherence guard's copy of their start frame: a
rigid copy, or one that may stretch at constant volume (``thrombojax rollout --coherence-stretch
S``, :func:`thrombojax.simulator.guards.coherence`'s ``max_stretch``).

For each ``S`` and every training simulation (neither ``--held-out`` nor ``--validation``), the
library's own :func:`thrombojax.eval.coherence_fit.clot_deviations` (every clot node's distance
from its place in the guard's copy of the rollout's start frame, vessel radii) is pooled over
(node, frame) pairs in two parts of the simulation: the steady run, before the exit, and the
exit, from the first frame step of ``../bendvessel_exit/exit_truth.exit_of`` on. The table gives
their 95th percentile and largest value, and :func:`~thrombojax.eval.coherence_fit.fit_coherence`
over all frames, the tolerance ``--coherence-tolerance auto`` takes with that copy. Also, per
simulation, the true clot's stretch along its motion in the exit's last frame (the least-squares
factor along the centroid's step, of the rigid copy; below 1: it shortens). No model is run; the
table is written atomically and replaced only with ``--force``. From the repository root::

    python experiments/results/ladder_budget/coherence_stretch/stretch_truth.py \\
        data/bendvessel.h5 --held-out bendvessel_005,bendvessel_012,bendvessel_019 \\
        --validation bendvessel_009 --stretch 1.05,1.1,1.2,1.3 --out stretch_truth.md

A simulation whose clot does not speed up at its end (no exit) counts wholly as steady; "-"
where no frame is in the exit.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import jax.numpy as jnp
import numpy as np

from thrombojax import study
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.coherence_fit import clot_deviations, fit_coherence
from thrombojax.eval.metrics import clot_centroids
from thrombojax.simulator.guards import coherence
from thrombojax.types import clot_mask

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "bendvessel_exit"))
from exit_truth import add_split_arguments, exit_of, open_split, write_table  # noqa: E402


def along_motion(pos: np.ndarray, clot: np.ndarray, start: int) -> float:
    """The last frame's stretch along the centroid's last step, against the start frame turned
    rigidly onto it (least squares along that direction)."""
    x, ref = pos[-1][clot], pos[start][clot]
    # the coherence guard's own rigid copy (stiffness 1, no tolerance: the copy itself)
    copy, _ = coherence(jnp.asarray(x), jnp.asarray(ref), jnp.ones(len(x), bool),
                        stiffness=1.0, tolerance=0.0)
    copy = np.asarray(copy, np.float64)
    p, q = x - x.mean(0), copy - copy.mean(0)
    m = x.mean(0) - pos[-2][clot].mean(0)
    m = m / np.linalg.norm(m)
    return float((p @ m) @ (q @ m) / ((q @ m) @ (q @ m)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_split_arguments(ap)
    ap.add_argument("--stretch", default="1.1,1.2,1.3", help="comma-separated S >= 1")
    args = ap.parse_args()
    ds, held, validation = open_split(args)
    left_out = held + validation
    names = [n for n in ds.names if n not in left_out]
    radius, start = float(vessel_radius(ds)), study.skip_frames(ds)
    exits, shorten, no_exit = {}, {}, []
    for name in names:
        pos, clot = ds.positions(name), clot_mask(ds.node_type(name))
        speed = np.linalg.norm(np.diff(clot_centroids(pos, clot) / radius, axis=0), axis=1)
        exits[name] = exit_of(speed)  # frame step k: frames k + 1 on are in the exit
        if exits[name] == len(speed):
            no_exit.append(name)
        shorten[name] = along_motion(pos, clot, start)
    lines = ["| copy | steady: p95 (r) | steady: largest (r) | exit: p95 (r) | exit: largest (r) "
             "| `auto` tolerance (r) |", "|---|---|---|---|---|---|"]
    for s in [None, *(float(v) for v in args.stretch.split(","))]:
        steady, exit_ = [], []
        for name in names:
            dev = clot_deviations(ds.positions(name), ds.node_type(name), start, radius,
                                  max_stretch=s)  # row i: frame start + 1 + i
            first = max(exits[name] + 1 - (start + 1), 0)
            steady.append(dev[:first].ravel())
            exit_.append(dev[first:].ravel())
        fit = fit_coherence(ds, names, radius, start, max_stretch=s)
        label = "rigid" if s is None else f"stretch up to {s:g}x"
        cells = [f"{np.quantile(d, 0.95):.3f} | {d.max():.3f}" if d.size else "- | -"
                 for d in (np.concatenate(steady), np.concatenate(exit_))]
        lines.append(f"| {label} | {' | '.join(cells)} | {fit['coherence_r']:.4f} |")
    values = np.array(list(shorten.values()))
    found = [exits[n] + 1 for n in names if n not in no_exit]
    span = f"from frame {min(found)}-{max(found)} on" if found else "nowhere"
    lines.append(f"\n{len(names)} training simulations, from the rollout's start (frame {start}); "
                 f"the exit {span}"
                 + (f" ({', '.join(no_exit)}: none)" if no_exit else "") + ". "
                 f"The true clot's stretch along its motion in the last frame: "
                 f"{values.min():.2f}-{values.max():.2f} (median {np.median(values):.2f}; "
                 "below 1: it shortens along the vessel and widens as it leaves it).")
    write_table(args.out, lines, radius)


if __name__ == "__main__":
    main()
