"""Subcommand that joins runs trained one by one into an ensemble: ``thrombojax ensemble``."""

from __future__ import annotations

__all__ = ["REGISTRARS"]


def _add_ensemble(sub) -> None:
    p = sub.add_parser(
        "ensemble",
        help="join runs trained one by one (e.g. with different --seed) into an ensemble "
             "folder that rollout reads",
        description=(
            "Join two or more training runs into one ensemble folder: DIR/ensemble.json lists "
            "the runs' absolute paths and seeds, so 'thrombojax rollout --run DIR' rolls every "
            "member out in one compiled program and writes the mean and the per-node spread. "
            "The runs must differ only by seed (the same model, model config, statistics, "
            "scaling and split) and each needs the checkpoint named by --checkpoint; this is "
            "checked before anything is written. The runs are neither copied nor changed: "
            "moving one breaks the ensemble. 'thrombojax train --members M' trains an "
            "ensemble in one folder instead."),
    )
    p.add_argument("runs", nargs="+", metavar="RUN", help="training run directories (two or "
                   "more), in member order")
    p.add_argument("--out", required=True, metavar="DIR", help="ensemble folder to write "
                   "(not inside a run)")
    p.add_argument("--checkpoint", default="best", choices=("best", "last"),
                   help="the checkpoint every run must have (default best; a rollout may "
                   "still choose the other with its own --checkpoint)")
    p.add_argument("--force", action="store_true", help="replace an existing "
                   "DIR/ensemble.json (never a run)")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=_run_ensemble)


def _run_ensemble(args) -> int:
    from thrombojax.train.ensemble import join_ensemble

    ens = join_ensemble(args.runs, args.out, which=args.checkpoint, force=args.force)
    if args.quiet:
        return 0
    seeds = ", ".join(map(str, ens.seeds))
    print(f"joined {ens.n_members} {ens.model.name} runs (seeds {seeds}) into "
          f"{args.out}/ensemble.json")
    print(f"roll it out with: thrombojax rollout --run {args.out} --dataset "
          f"{ens.run.dataset} --out DIR --checkpoint {args.checkpoint}")
    return 0


REGISTRARS = [_add_ensemble]
