"""The ``thrombojax experiment`` subcommand: ``list`` the study's experiments, ``run`` one."""

from __future__ import annotations

from thrombojax.cli.options import output_flags

__all__ = ["REGISTRARS"]


def _add_experiment(sub) -> None:
    p = sub.add_parser(
        "experiment",
        help="the study's experiments from one command: list them, run one at a scale",
        description=(
            "Each experiment (experiments/configs/<name>.toml) reproduces one result of the "
            "study at three scales: smoke (seconds), cpu (hours on a 2-core CPU), study (the "
            "study's settings, for a GPU or a cluster). 'run' generates the datasets it needs, "
            "trains and measures every run (one folder each, resumable), aggregates seeds and "
            "writes table.md with the study's numbers beside ours, and the plots."
        ),
    )
    esub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    lp = esub.add_parser("list", help="every experiment, what it reproduces, its cost per scale")
    lp.add_argument("--config-dir", metavar="DIR", help="folder of experiment files "
                    "(default: experiments/configs)")
    lp.set_defaults(func=_run_list)
    rp = esub.add_parser("run", help="run (or resume) an experiment at a scale")
    rp.add_argument("name", help="experiment name (see 'thrombojax experiment list') or a "
                    ".toml file")
    rp.add_argument("--scale", required=True, choices=("smoke", "cpu", "study"))
    rp.add_argument("--out", required=True, metavar="DIR", help="experiment folder (a second "
                    "run of the same command resumes it)")
    rp.add_argument("--seeds", metavar="N|LIST", help="seeds: a count (5: seeds 0-4) or a "
                    "comma-separated list (default: the scale's)")
    rp.add_argument("--worker", metavar="I/N", help="run only every N-th run from the I-th "
                    "(0-based; e.g. a Slurm array task: $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_"
                    "COUNT)")
    rp.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="sets",
                    help="override a field of the scale (TOML value): train.epochs=5, "
                    "models=[\"mgn\"], model_config.mgn.hidden=64, options.trials=20")
    rp.add_argument("--data-dir", metavar="DIR", help="dataset cache (default: DIR/data)")
    rp.add_argument("--dataset", action="append", metavar="PRESET=FILE", help="use this "
                    "dataset file for a preset instead of generating it (repeatable)")
    rp.add_argument("--storage", metavar="URL", help="search only: Optuna storage (default "
                    "sqlite:///DIR/search.db; any RDB URL shares one study between hosts)")
    rp.add_argument("--trials", type=int, metavar="N", help="search only: total trials")
    rp.add_argument("--config-dir", metavar="DIR", help="folder of experiment files")
    rp.add_argument("--dry-run", action="store_true", help="print this worker's runs and the "
                    "cost estimate; run nothing")
    output_flags(rp, "redo every run (and refuse nothing in DIR); datasets are kept")
    rp.set_defaults(func=_run_run)


def _seeds(text: str | None) -> tuple[int, ...] | None:
    from thrombojax.errors import ConfigError

    if text is None:
        return None
    try:
        items = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise ConfigError(f"--seeds expects a count or a list of integers, got '{text}'") from None
    if len(items) == 1 and "," not in text:
        if items[0] < 1:
            raise ConfigError(f"--seeds {text}: a count of seeds must be >= 1 (for seed "
                              f"{items[0]} alone give a list: --seeds {items[0]},)")
        items = list(range(items[0]))
    if not items or min(items) < 0:
        raise ConfigError(f"--seeds {text}: need at least one seed, all >= 0")
    return tuple(items)


def _hours(seconds: float | None) -> str:
    if seconds is None:
        return "time unknown (no step time recorded)"
    if seconds < 120:
        return f"~{seconds:.0f} s"
    return f"~{seconds / 60:.0f} min" if seconds < 7200 else f"~{seconds / 3600:.1f} h"


def _run_list(args) -> int:
    from thrombojax.experiments.plan import estimate
    from thrombojax.experiments.spec import SCALES, list_experiments

    for exp in list_experiments(args.config_dir):
        print(f"{exp.name} ({exp.kind}): {exp.title}")
        print(f"  reproduces: {exp.reproduces}")
        for scale in SCALES:
            est = estimate(exp, scale)
            print(f"  {scale:5s}: {est['runs']} runs, {est['steps']:,} training steps, "
                  f"{_hours(est['seconds'])}")
        print(f"  cost: {estimate(exp, 'cpu')['how']}")
    return 0


def _dry_run(exp, args) -> int:
    from thrombojax.experiments.plan import estimate, parse_worker, plan_runs, shard

    runs = plan_runs(exp, args.scale, _seeds(args.seeds))
    mine = shard(runs, parse_worker(args.worker))
    for run in mine:
        print(f"{run.key}: {run.model} on {run.dataset or '-'}, seed {run.seed}, "
              f"{run.train.epochs} epochs")
    est = estimate(exp, args.scale)
    print(f"{len(mine)} of {len(runs)} runs; the whole scale: {est['steps']:,} training steps, "
          f"{_hours(est['seconds'])} ({est['how']})")
    return 0


def _run_run(args) -> int:
    from thrombojax.errors import ConfigError
    from thrombojax.experiments.data import parse_dataset_overrides
    from thrombojax.experiments.plan import parse_worker
    from thrombojax.experiments.runner import run_experiment
    from thrombojax.experiments.spec import apply_sets, find_experiment

    exp = find_experiment(args.name, args.config_dir)
    exp = apply_sets(exp, args.scale, args.sets)
    search_only = [f for f, v in (("--storage", args.storage), ("--trials", args.trials)) if v]
    if exp.kind != "search" and search_only:
        raise ConfigError(f"{', '.join(search_only)}: only for a search; '{exp.name}' is a "
                          f"{exp.kind}")
    if exp.kind == "search" and (args.worker or args.seeds):
        raise ConfigError("--worker/--seeds do not apply to a search: start the same command "
                          "on each host with one shared --storage")
    if args.trials is not None and args.trials < 1:
        raise ConfigError(f"--trials must be >= 1, got {args.trials}")
    if args.dry_run:
        return _dry_run(exp, args)
    if exp.kind == "search":
        from thrombojax.experiments.search import run_search

        res = run_search(exp, args.scale, args.out, storage=args.storage, trials=args.trials,
                         force=args.force, progress=not args.quiet, data_dir=args.data_dir,
                         datasets=parse_dataset_overrides(args.dataset))
        print(res["report"]["table"], end="")
        print(f"best trial's config: {res['best_config']} (thrombojax train --config ...)")
        return 0
    res = run_experiment(exp, args.scale, args.out, seeds=_seeds(args.seeds),
                         worker=parse_worker(args.worker), data_dir=args.data_dir,
                         datasets=parse_dataset_overrides(args.dataset), force=args.force,
                         progress=not args.quiet)
    print(f"{exp.name} ({args.scale}): {res['ran']} runs ran, {res['skipped']} already "
          f"finished, {res['finished']} of {res['runs']} done")
    if res["report"]:
        print(res["report"]["table"], end="")
        for path in res["report"]["files"]:
            print(f"wrote {path}")
    return 0


REGISTRARS = [_add_experiment]
