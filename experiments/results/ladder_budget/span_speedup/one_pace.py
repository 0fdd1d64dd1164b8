"""How far off a rollout ends that runs every simulation at the training simulations' mean pace.

No model is run. Per simulation, the clot centroid's travel along its own path (the sum of its
frame-to-frame steps, in vessel radii) from the rollout's start frame ``T0`` (the dataset's
``skip_frames``) to the end of the record. A rollout that follows each clot's true path exactly
but moves along it as the *mean* training simulation does ends ``mean travel - own travel``
along the track: the part of the final error that a step which does not tell the simulations
apart cannot avoid, whatever its guards (``along``: + ahead). The travel is split at the exit
(the last ``EXIT`` frames, as ``../start_span/exit_read.py`` counts them). The same for the
training simulations themselves (each against the mean of the others) gives the spread a
one-pace step leaves on vessels it was trained on.

Run from the repository root::

    python experiments/results/ladder_budget/span_speedup/one_pace.py OUT.md DATA TRAIN SIMS

``TRAIN`` and ``SIMS`` are comma-separated simulation names (the training simulations, and the
ones to report). It writes (never over an existing OUT.md) and prints the Markdown table, then
the date, command, device, versions, CPU and load.
"""

from __future__ import annotations

import pathlib
import sys

import numpy as np

from thrombojax.data.radius import vessel_radius
from thrombojax.eval.metrics import clot_centroids
from thrombojax.eval.tables import measured_line
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.study import skip_frames
from thrombojax.types import clot_mask

EXIT = 6
"""Frames at the end of the record counted as the exit (``../start_span/exit_read.py``)."""


def travel(ds, sim: str, t0: int, unit: float) -> np.ndarray:
    """The clot centroid's travel, r, ``[2]``: from ``T0`` to the exit, and in the exit."""
    pos = np.asarray(ds.positions(sim), np.float64)
    centre = clot_centroids(pos, clot_mask(np.asarray(ds.node_type(sim))))
    steps = np.linalg.norm(np.diff(centre[t0:], axis=0), axis=1) / unit
    return np.array([steps[:-EXIT].sum(), steps[-EXIT:].sum()])


def main(argv: list[str]) -> None:
    out, data = pathlib.Path(argv[0]), argv[1]
    train, sims = argv[2].split(","), argv[3].split(",")
    check_targets([out], force=False)
    ds = open_dataset(data)
    t0, unit = skip_frames(ds), vessel_radius(ds)
    own = {s: travel(ds, s, t0, unit) for s in dict.fromkeys(train + sims)}
    lines = [f"{data}: travel along the true path from frame {t0} (T0), r; the exit its last "
             f"{EXIT} frames. A one-pace rollout moves as the mean of the {len(train)} training "
             "simulations (a training simulation: the mean of the others) and ends `mean - own` "
             "along the track (+ ahead).", "",
             "| simulation | travel: to the exit / in it / all | one pace, along: before the exit "
             "/ in it / final |", "|---|---|---|"]
    finals = {"reported": [], "training": []}
    for s in list(sims) + [t for t in train if t not in sims]:
        others = [own[t] for t in train if t != s]
        off = np.mean(others, axis=0) - own[s]
        finals["training" if s in train and s not in sims else "reported"].append(off.sum())
        lines.append(f"| {s}{' (training)' if s in train else ''} | {own[s][0]:.2f} / "
                     f"{own[s][1]:.2f} / {own[s].sum():.2f} | {off[0]:+.2f} / {off[1]:+.2f} / "
                     f"{off.sum():+.2f} |")
    lines += ["", "| simulations | one pace: mean absolute final along (r) | largest |",
              "|---|---|---|"]
    for kind, v in finals.items():
        if v:
            v = np.abs(v)
            lines.append(f"| {kind} ({len(v)}) | {v.mean():.2f} | {v.max():.2f} |")
    lines += ["", measured_line()]
    atomic_write_text(out, "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1:])
