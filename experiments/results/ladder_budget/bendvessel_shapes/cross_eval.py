"""Roll trained runs out on chosen simulations of any dataset and write the ladder's table
(``table.md``, ``ladder.json``, ``error_per_step.png``) into OUT; each row's result is kept in
``OUT/<label>.json`` and reused when the command is run again. Run from the repository root::

    python experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py [--nodes N] \\
        [--sims-kind TEXT] OUT DATA NAME1,NAME2,... "TITLE" LABEL=RUN[+RUN...][:guards] ...

``--nodes N`` rolls out on the fixed subset of N nodes per simulation that the ladder's
``--nodes`` uses (ClotEntry: 2,048); without it, all nodes. ``--sims-kind TEXT`` is what the
table's title calls the simulations (default "held-out simulations"; e.g. "training
simulations").

Every run is evaluated at its last checkpoint; ``+`` joins runs into an ensemble (score a member
alone with a row of its own); ``:guards`` turns the physics guards on, and
``:guards,NAME=VALUE,...`` sets their options (numbers, keyword arguments of
``thrombojax.simulator.guard_set.build_guards``, e.g. ``:guards,tolerance_r=0.3``, the coherence
guard's tolerance in vessel radii), except ``rotations=R``: every model also rolled out on
``R`` turned copies of each simulation (``fixed_rotations(R)``, the first unturned), all
members of one ensemble (``thrombojax rollout --rotations R``), and ``centre_pull=K`` with
``centre_tolerance_r=T``: the vessel-following prior's centring pull set at rollout time
(``thrombojax rollout --centre-pull K --centre-tolerance T``; a flag other than ``guards``,
e.g. ``:alone,centre_pull=0.5``, keeps the guards off). Each row's JSON keeps
the environment it was measured in (``measured``); the tables' closing lines are those of the
process that wrote them.
"""

import json
import pathlib
import sys

sys.path.insert(0, "experiments")
from ladder_eval import evaluate_runs  # noqa: E402
from ladder_report import write_reports  # noqa: E402

from thrombojax.data.radius import vessel_radius  # noqa: E402
from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.io.hdf5 import open_dataset  # noqa: E402
from thrombojax.io.outputs import atomic_write_text  # noqa: E402


def _pull_options(run: str, data: str, strength: float, tolerance_r: float) -> dict | None:
    """The learned step's fields of a centring pull at rollout time (None: the run's own), in
    the run's scaled units with the rolled-out vessel's radius as the unit."""
    if not strength:
        return None
    scale = json.loads((pathlib.Path(run) / "config.json").read_text())["scaling"]["scale"]
    unit = float(vessel_radius(open_dataset(data))) / float(scale)
    return {"centre_pull": float(strength), "centre_unit": unit,
            "centre_tolerance": float(tolerance_r) * unit}


def main() -> None:
    argv, nodes, sims_kind = sys.argv[1:], None, "held-out simulations"
    while argv and argv[0] in ("--nodes", "--sims-kind"):
        if argv[0] == "--nodes":
            nodes = int(argv[1])
        else:
            sims_kind = argv[1]
        argv = argv[2:]
    out, data, names, title = pathlib.Path(argv[0]), argv[1], argv[2].split(","), argv[3]
    out.mkdir(parents=True, exist_ok=True)
    results = {}
    for spec in argv[4:]:
        label, _, rest = spec.partition("=")
        runs, _, flag = rest.partition(":")
        flag, *options = flag.split(",") if flag else [""]
        guard_options = {k: float(v) for k, v in (o.split("=", 1) for o in options)}
        rotations = int(guard_options.pop("rotations", 0))
        step_options = _pull_options(runs.split("+")[0], data,
                                     guard_options.pop("centre_pull", 0.0),
                                     guard_options.pop("centre_tolerance_r", 0.0))
        guard_options = guard_options or None
        path = out / f"{label}.json"
        if path.is_file():
            results[label] = json.loads(path.read_text())
            if nodes is not None and results[label].get("n_nodes") != nodes:
                sys.exit(f"{path}: row {label!r} was measured on {results[label].get('n_nodes')} "
                         f"nodes per simulation, not --nodes {nodes}; move it away to measure "
                         "it again")
            continue
        print("evaluating", label, flush=True)
        results[label] = evaluate_runs([pathlib.Path(r) for r in runs.split("+")], data,
                                       flag == "guards", nodes, names, "last",
                                       guard_options=guard_options, rotations=rotations,
                                       step_options=step_options)
        results[label]["measured"] = environment()
        atomic_write_text(path, json.dumps(results[label], indent=1))
    print(write_reports(out, results, title=title, test_sims=names, nodes=nodes,
                        sims_kind=sims_kind))


if __name__ == "__main__":
    main()
