"""How deep the clot nodes outside the vessel wall lie in rollouts, in vessel radii.

Reads the ``<sim>_rollout.h5`` files that ``thrombojax rollout`` writes (dataset schema, the
dataset's length unit) and prints one markdown table: per rollout file, the largest share of
the clot outside, and the depth of the outside nodes over every frame (median, 90th percentile,
largest), with "outside" as the rollout tables count it (``fraction_outside`` in
``thrombojax/eval/metrics.py``: signed wall distance over half the wall-node spacing, nodes past
an open end excluded). Run from the repository root::

    python experiments/results/ladder_budget/bendvessel_hold/outside_depth.py DATA \\
        LABEL=ROLLOUT_DIR [LABEL=ROLLOUT_DIR ...]

``DATA`` is the dataset the rollouts came from (its vessel radius sets the unit).
"""

import pathlib
import sys

import numpy as np

from thrombojax.data.radius import vessel_radius
from thrombojax.eval.metrics import fit_vessel_wall, fraction_outside, signed_wall_distance
from thrombojax.io.hdf5 import open_dataset
from thrombojax.types import clot_mask


def depths(path: pathlib.Path, radius: float) -> tuple[float, np.ndarray]:
    """(largest share of the clot outside over the frames, depths of all outside node-frames)."""
    ds = open_dataset(path)
    (name,) = ds.names
    sim = ds[name]
    pos, nt = np.asarray(sim.positions), np.asarray(sim.node_type)
    wall = fit_vessel_wall(pos[0], nt, wall_cells=sim.wall_cells)
    clot = clot_mask(nt)
    share = float(fraction_outside(wall, pos, clot).max())  # the rollout tables' figure
    s, past = signed_wall_distance(wall, pos[:, clot], return_past_end=True)
    return share, s[(s > 0.5 * wall.spacing) & ~past] / radius  # fraction_outside's test


def main() -> None:
    data, specs = sys.argv[1], sys.argv[2:]
    radius = float(vessel_radius(open_dataset(data)))
    print("| model | simulation | max clot outside | depth outside (r): median / 90 % / largest |")
    print("|---|---|---|---|")
    for spec in specs:
        label, _, folder = spec.partition("=")
        for path in sorted(pathlib.Path(folder).glob("*_rollout.h5")):
            share, d = depths(path, radius)
            cells = (f"{np.median(d):.2f} / {np.quantile(d, 0.9):.2f} / {d.max():.2f}"
                     if d.size else "-")
            print(f"| {label} | {path.name.removesuffix('_rollout.h5')} | {share:.1%} | {cells} |")
    print(f"\nvessel radius {radius:g} ({data}); command: {' '.join(sys.argv)}")


if __name__ == "__main__":
    main()
