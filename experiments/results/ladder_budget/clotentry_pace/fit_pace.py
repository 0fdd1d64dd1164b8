"""Fit the pace of trained runs (one model, or ``+``-joined runs as one ensemble) on
simulations they were not tested on, and write the fit to ``OUT.json``. Run from the repository
root::

    python experiments/results/ladder_budget/clotentry_pace/fit_pace.py [--nodes N] OUT.json \\
        DATA NAME1,NAME2,... RUN[+RUN...]

Every run at its last checkpoint, guarded rollouts from the dataset's first rolled-out frame
(as ``experiments/ladder_eval.py``); the search is
``thrombojax.eval.pace_fit.fit_pace_on_simulations``. The JSON keeps the environment it was
measured in (``measured``).
"""

import json
import pathlib
import sys

from thrombojax import study
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.pace_fit import fit_pace_on_simulations
from thrombojax.eval.single_step import scaled_simulation
from thrombojax.eval.tables import environment
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text
from thrombojax.simulator.ensemble import stack_params
from thrombojax.train.state import load_trained


def main() -> None:
    argv, nodes = sys.argv[1:], None
    if argv[:1] == ["--nodes"]:
        nodes, argv = int(argv[1]), argv[2:]
    out, data, names, runs = pathlib.Path(argv[0]), argv[1], argv[2].split(","), argv[3]
    if out.exists():
        sys.exit(f"{out} exists; move it away to fit again")
    members = [load_trained(pathlib.Path(r), which="last") for r in runs.split("+")]
    trained = members[0]
    ds = open_dataset(data)
    sims = [(n, *scaled_simulation(ds, n, trained.scaling), ds[n].wall_cells) for n in names]
    ensemble = len(members) > 1
    params = stack_params([m.params for m in members]) if ensemble else trained.params
    fit = fit_pace_on_simulations(
        trained.step, params, trained.stats, sims,
        radius=vessel_radius(ds) / float(trained.scaling.scale),
        t0=max(study.skip_frames(ds), 1), n_nodes=nodes, ensemble=ensemble)
    fit |= {"runs": runs.split("+"), "dataset": data, "n_nodes": nodes,
            "measured": environment()}
    atomic_write_text(out, json.dumps(fit, indent=1))
    print(json.dumps({k: fit[k] for k in ("pace", "along_r", "evaluations", "track_length_r")}))


if __name__ == "__main__":
    main()
