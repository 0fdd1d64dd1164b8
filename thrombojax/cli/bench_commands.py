"""Subcommand that times rollouts at the study's sizes: ``thrombojax bench``."""

from __future__ import annotations

from thrombojax.cli.options import POS_INT, output_flags

__all__ = ["REGISTRARS"]


def _add_bench(sub) -> None:
    p = sub.add_parser(
        "bench",
        help="time rollouts at the study's sizes; speed-up over Abaqus and our solver",
        description=(
            "For each model and size (bendvessel: 35 steps x 977 nodes; clotentry: 160 x 2048; "
            "clotentry-full: 160 x 27000) report compile time, steady-state rollout time, "
            "per-step time, the time scaled to the whole simulation and the speed-up over the "
            "study's Abaqus times (180 s / 1500 s) and our solver's measured time. Models are "
            "random-initialised (timing needs no trained weights) unless --run is given. "
            "Writes bench.json and bench.md with device, versions and date."
        ),
    )
    p.add_argument("--models", default="mgn,transolver,erwin", help="comma-separated models")
    p.add_argument("--cases", default="bendvessel,clotentry,clotentry-full",
                   help="comma-separated sizes: bendvessel, clotentry, clotentry-full")
    p.add_argument("--run", action="append", metavar="MODEL=DIR", default=[],
                   help="time a trained run for MODEL (repeatable)")
    p.add_argument("--tiny", action="store_true", help="tiny configs instead of the study's")
    p.add_argument("--nodes", type=POS_INT, help="override every case's node count")
    p.add_argument("--max-steps", type=POS_INT,
                   help="time at most this many steps; extrapolate")
    p.add_argument("--repeats", type=POS_INT, default=3, help="steady-state repetitions (median)")
    p.add_argument("--dataset", metavar="FILE", help="take positions from this dataset")
    p.add_argument("--solver-dataset", action="append", default=[], metavar="FILE",
                   help="dataset whose solver_wall_time_s is our solver's time (repeatable)")
    p.add_argument("--measure-solver", action="append", default=[], metavar="PRESET",
                   help="run this solver preset once now to time our solver (repeatable)")
    p.add_argument("--out", metavar="DIR", help="write bench.json and bench.md here")
    output_flags(p, "replace existing bench.json / bench.md")
    p.set_defaults(func=_run_bench)


def _run_bench(args) -> int:
    from thrombojax.errors import ConfigError
    from thrombojax.eval.bench import bench

    runs = {}
    for item in args.run:
        if "=" not in item:
            raise ConfigError(f"--run expects MODEL=DIR, got '{item}'")
        name, path = item.split("=", 1)
        runs[name] = path
    res = bench(tuple(m for m in args.models.split(",") if m),
                tuple(c for c in args.cases.split(",") if c), runs=runs, tiny=args.tiny,
                n_nodes=args.nodes, max_steps=args.max_steps, repeats=args.repeats,
                dataset=args.dataset, solver_datasets=tuple(args.solver_dataset),
                measure_solver=tuple(args.measure_solver), out_dir=args.out,
                progress=not args.quiet, force=args.force)
    print(res["table"], end="")
    for path in res.get("files", []):
        print(f"wrote {path}")
    return 0


REGISTRARS = [_add_bench]
