"""Where the rollout's clot is along the vessel, node by node: does it move ahead as one body,
or does it stretch?

A rollout's clot centroid runs 1.2-3.5 r ahead of the true clot on BendVessel-sized vessels
before the exit (``exit_split.py``), and its radius of gyration grows to 1.6-1.8 times the true
clot's. This rolls a run out alone (its last checkpoint, as ``../cross_eval.py``) on given
simulations and, every 4 steps, places every clot node along the true clot's direction of motion
(``u``, the true centroid's step) about the true centroid: percentiles 0, 10, 50, 90 and 100 of
``(x_i - c_true) . u`` for the prediction and the truth, in vessel radii. Output: JSON with the
command, versions, date and load, and a printed table.

Run from the repository root::

    python experiments/results/ladder_budget/bendvessel_shapes/exit/stretch.py OUT.json \\
        data/bendvessel_shapes.h5 bendvessel-shapes_005,bendvessel-shapes_012 LABEL=RUN ...
"""

from __future__ import annotations

import json

import numpy as np
import script_args

from thrombojax.data.radius import vessel_radius
from thrombojax.eval.single_step import scaled_simulation
from thrombojax.eval.tables import environment
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text
from thrombojax.simulator.rollout import rollout
from thrombojax.study import skip_frames
from thrombojax.train.state import load_trained
from thrombojax.types import clot_mask

PERCENTILES = (0, 10, 50, 90, 100)
EVERY = 4


def along_spread(run: str, data: str, name: str) -> dict:
    """Per reported step: the percentiles of the clot nodes' places along the true motion about
    the true centroid, predicted and true (vessel radii)."""
    trained = load_trained(run, which="last")
    step, ds = trained.step, open_dataset(data)
    r = vessel_radius(ds) / float(trained.scaling.scale)
    pos, nt = scaled_simulation(ds, name, trained.scaling)
    skip = max(skip_frames(ds), 1)
    mask = np.ones(len(nt), bool)
    clot = np.asarray(clot_mask(nt, mask), bool)
    n = pos.shape[0] - 1 - skip
    pred = np.asarray(rollout(step, trained.params, trained.stats, step.previous(pos, skip),
                              pos[skip], nt, mask, n), np.float64)
    frames = pos[skip:].astype(np.float64)  # frames[k + 1] is the truth of pred[k]
    rows = []
    for k in range(0, n, EVERY):
        c_true = frames[k + 1][clot].mean(axis=0)
        u = c_true - frames[k][clot].mean(axis=0)
        u /= np.linalg.norm(u)
        place = {what: np.percentile((x[clot] - c_true) @ u / r, PERCENTILES).tolist()
                 for what, x in (("pred", pred[k]), ("true", frames[k + 1]))}
        rows.append({"step": k + 1, **place})
    return {"steps": rows}


def main() -> None:
    out_path, data, names, runs = script_args.parse(__doc__)
    result = {**environment(), "percentiles": PERCENTILES, "data": data, "runs": {}}
    for label, run in runs.items():
        result["runs"][label] = {"run": run, "simulations": {}}
        for name in names:
            sim = along_spread(run, data, name)
            result["runs"][label]["simulations"][name] = sim
            print(f"{label} {name}: place along the motion (r), p0 / p10 / p50 / p90 / p100")
            for row in sim["steps"]:
                fmt = " ".join(f"{v:+.2f}" for v in row["pred"])
                true = " ".join(f"{v:+.2f}" for v in row["true"])
                print(f"  step {row['step']:2d}  predicted {fmt}   true {true}")
    atomic_write_text(out_path, json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
