"""Which BendVessel training windows ``thrombojax train --speedup-weight W --speedup-fraction F``
weighs up, and where in the simulation they lie.

For every ``s_{t-1}, s_t, s_{t+1}`` window of the training simulations (neither ``--held-out``
nor ``--validation``), :func:`thrombojax.train.speedup.speedup_window_weight` (the library's own
test, run on the clean frames) says whether the window weighs ``1 + W``. Each weighted window is
counted as the start (``t`` before the first steady frame of ``../bendvessel_exit/exit_truth.py``)
or the exit (from the exit's first frame step on, as ``exit_truth.exit_of`` finds it), else
elsewhere; with ``W``, the share of the loss those windows carry (clot nodes are the same in
every window of a simulation, so windows count alike). No model is run; the table is written
atomically and replaced only with ``--force``. From the repository root::

    python experiments/results/ladder_budget/bendvessel_exit_levers/speedup_windows.py \\
        data/bendvessel.h5 --held-out bendvessel_005,bendvessel_012,bendvessel_019 \\
        --validation bendvessel_009 --weight 3 --fraction 0.1 --out speedup_windows.md
"""

from __future__ import annotations

import argparse
import functools
import pathlib
import sys

import jax
import numpy as np

from thrombojax.data.radius import vessel_radius
from thrombojax.eval.metrics import clot_centroids
from thrombojax.train.speedup import speedup_window_weight
from thrombojax.types import clot_mask

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "bendvessel_exit"))
from exit_truth import (  # noqa: E402
    STEADY_FRAMES,
    add_split_arguments,
    exit_of,
    open_split,
    write_table,
)


@functools.partial(jax.jit, static_argnames="fraction")
def _weights(windows, node_type, mask, *, fraction: float):
    """:func:`speedup_window_weight` (weight 1) of every three-frame window ``[W, 3, N, 3]``."""
    return jax.vmap(lambda w: speedup_window_weight(w, node_type, mask, current=1, weight=1.0,
                                                    fraction=fraction))(windows)


def count(ds, name: str, radius: float, fraction: float) -> dict:
    """The weighted windows of one simulation: their ``t`` and where they lie."""
    pos, nt = ds.positions(name), ds.node_type(name)
    mask = np.ones(len(nt), bool)
    speed = np.linalg.norm(np.diff(clot_centroids(pos, clot_mask(nt)) / radius, axis=0), axis=1)
    k = exit_of(speed)
    windows = np.stack([pos[t - 1:t + 2] for t in range(1, len(pos) - 1)])
    weights = np.asarray(_weights(windows, nt, mask, fraction=fraction))
    ts = [int(t) + 1 for t in np.flatnonzero(weights > 1.0)]  # window i holds s_t at t = i + 1
    return {"name": name, "windows": len(pos) - 2, "ts": ts, "exit_from": k,
            "start": sum(t < STEADY_FRAMES.start for t in ts), "exit": sum(t >= k for t in ts)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_split_arguments(ap)
    ap.add_argument("--weight", type=float, required=True, help="--speedup-weight W")
    ap.add_argument("--fraction", type=float, default=0.1, help="--speedup-fraction F")
    args = ap.parse_args()
    ds, held, validation = open_split(args)
    left_out = held + validation
    radius = float(vessel_radius(ds))
    rows = [count(ds, n, radius, args.fraction) for n in ds.names if n not in left_out]
    lines = ["| simulation | weighted windows (t) | exit from frame step | start | exit | "
             "elsewhere |", "|---|---|---|---|---|---|"]
    lines += [f"| {r['name']} | {', '.join(map(str, r['ts']))} | {r['exit_from']} | "
              f"{r['start']} | {r['exit']} | {len(r['ts']) - r['start'] - r['exit']} |"
              for r in rows]
    total = sum(r["windows"] for r in rows)
    weighted = sum(len(r["ts"]) for r in rows)
    start, exit_ = sum(r["start"] for r in rows), sum(r["exit"] for r in rows)
    mass = (1 + args.weight) * weighted / (total + args.weight * weighted)
    exit_mass = (1 + args.weight) * exit_ / (total + args.weight * weighted)
    lines.append(f"\n`--speedup-fraction {args.fraction:g}` weighs {weighted} of the {total} "
                 f"training windows ({100 * weighted / total:.1f} %): {start} at the start, "
                 f"{exit_} in the exit, {weighted - start - exit_} elsewhere. With "
                 f"`--speedup-weight {args.weight:g}` they carry {100 * mass:.0f} % of the loss, "
                 f"the exit's {100 * exit_mass:.0f} % (before: {100 * exit_ / total:.0f} %).")
    write_table(args.out, lines, radius)


if __name__ == "__main__":
    main()
