"""What a dataset's start from rest says of its simulations: a table and correlations.

Per simulation, from the true clot centroid (in vessel radii per frame): the drive ratio and
flow speed the generator drew, the mean speed from rest to the rollout's start frame ``T0`` (the
dataset's ``skip_frames``; what ``thrombojax train --start-speed --start-span T0`` gives the
step), the speed into ``T0`` (``--start-speed`` alone), the mean speed after ``T0`` and the
end's speed-up (the mean speed of the last 3 frames minus that of the 15 after ``T0``). Then the
correlations, over the simulations, of the two start speeds with the others.

Run from the repository root::

    python experiments/results/ladder_budget/start_span/facts.py OUT.md DATA

It writes (never over an existing OUT.md) and prints the Markdown.
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

COLUMNS = ("drive ratio", "flow speed", "mean speed 0..T0", "speed into T0",
           "mean speed after T0", "end's speed-up")


def simulation_row(ds, sim, t0: int, unit: float) -> list[float]:
    """The :data:`COLUMNS` of one simulation (speeds in vessel radii per frame)."""
    pos = np.asarray(ds.positions(sim), np.float64)
    centre = clot_centroids(pos, clot_mask(np.asarray(ds.node_type(sim))))
    speed = np.linalg.norm(np.diff(centre, axis=0), axis=1) / unit
    travel = np.linalg.norm(centre[t0] - centre[0]) / unit
    return [np.nan, np.nan, travel / t0, speed[t0 - 1], speed[t0:].mean(),
            speed[-3:].mean() - speed[t0:t0 + 15].mean()]


def main(argv):
    out, data = pathlib.Path(argv[0]), argv[1]
    check_targets([out], force=False)
    ds = open_dataset(data)
    t0, unit = max(skip_frames(ds), 1), vessel_radius(ds)
    rows = {}
    for sim in ds.names:
        attrs = ds.sim_attrs(sim)  # the generator's draws, where the file records them
        rows[sim] = simulation_row(ds, sim, t0, unit)
        rows[sim][:2] = [float(attrs.get(k, np.nan)) for k in ("drive_ratio", "flow_speed")]
    lines = [f"{data}: T0 = {t0}; speeds in vessel radii per frame.", "",
             "| simulation | " + " | ".join(COLUMNS) + " |", "|---" * (len(COLUMNS) + 1) + "|"]
    lines += [f"| {sim} | " + " | ".join(f"{v:.3f}" for v in row) + " |"
              for sim, row in rows.items()]
    table = np.array(list(rows.values()))
    lines += ["", "| correlation over the simulations | " + " | ".join(
        COLUMNS[j] for j in (0, 1, 4, 5)) + " |", "|---|---|---|---|---|"]
    for i in (2, 3):
        lines.append(f"| {COLUMNS[i]} | " + " | ".join(
            f"{np.corrcoef(table[:, i], table[:, j])[0, 1]:.2f}" for j in (0, 1, 4, 5)) + " |")
    lines += ["", measured_line()]
    atomic_write_text(out, "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1:])
