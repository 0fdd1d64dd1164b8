"""Subcommands that measure trained runs: evaluate, rollout (train: :mod:`.train_commands`)."""

from __future__ import annotations

from thrombojax.cli.options import (
    NN_FLOAT,
    NN_INT,
    POS_INT,
    auto_radii,
    float_at_least,
    output_flags,
)

__all__ = ["REGISTRARS"]


def _add_evaluate(sub) -> None:
    p = sub.add_parser(
        "evaluate",
        help="single-step MSE of a trained run on any dataset, by phase, beside constant velocity",
        description=(
            "Teacher-forced one-step prediction on every window of the chosen simulations: MSE "
            "over clot nodes in scaled [-1, 1] coordinates (the study's metric) and in vessel "
            "radii, beside the constant-velocity baseline with the ratio model / CV, split by "
            "phase: start from rest (frames before the dataset's skip_frames attribute), the "
            "rollout phase, and the exit (from the first frame with a clot node past the "
            "vessel's open end). By default the run's test split on its own dataset, every "
            "simulation of any other dataset (train on A, evaluate on B). Writes evaluate.json "
            "and evaluate.md."
        ),
    )
    p.add_argument("--run", required=True, metavar="DIR", help="training run directory")
    p.add_argument("--dataset", required=True, metavar="FILE", help="dataset .h5 file (the "
                   "run's own or another one in the same length unit)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: the run directory)")
    p.add_argument("--sim", action="append", metavar="NAME",
                   help="simulation to evaluate (repeatable; default: see --split)")
    p.add_argument("--split", choices=("train", "val", "test", "all"),
                   help="the run's split to evaluate (default: test on the run's own dataset, "
                   "all simulations of another dataset)")
    p.add_argument("--checkpoint", default="best", choices=("best", "last"))
    p.add_argument("--skip", type=NN_INT, default=0,
                   help="leave out windows whose middle frame < SKIP (default 0; the phases "
                   "split at the dataset's skip_frames whatever SKIP is)")
    p.add_argument("--nodes", type=POS_INT, help="fixed seeded node subset (default: the "
                   "run's nodes_per_sample, else all nodes)")
    output_flags(p, "replace existing evaluate.json / evaluate.md")
    p.set_defaults(func=_run_evaluate)


def _run_evaluate(args) -> int:
    from thrombojax.eval.single_step import evaluate_run

    res = evaluate_run(args.run, args.dataset, out_dir=args.out, simulations=args.sim,
                       split=args.split, which=args.checkpoint, skip=args.skip,
                       n_nodes=args.nodes, progress=not args.quiet, force=args.force)
    print(f"simulations: {res['selection']['how']}")
    print(res["table"], end="")
    print(f"wrote {args.out or args.run}/evaluate.json and evaluate.md")
    return 0


def _add_rollout(sub) -> None:
    p = sub.add_parser(
        "rollout",
        help="roll a trained run out: trajectory HDF5, ParaView series, GIF, error plots",
        description=(
            "Autoregressive rollout (one compiled jax.lax.scan) of a trained run on dataset "
            "simulations, starting after the dataset's skipped frames (its skip_frames attribute: "
            "5 BendVessel, 40 ClotEntry, as in the study). "
            "Writes per simulation: <sim>_rollout.h5 (dataset schema), <sim>_prediction.xdmf and "
            "<sim>_truth.xdmf (node types and error as point data), <sim>_rollout.gif (prediction "
            "beside ground truth), <sim>_error.png and <sim>_metrics.png (with the "
            "constant-velocity baseline), plus rollout.json and rollout.md (every error in "
            "scaled units and vessel radii, beside constant velocity). Any dataset in the run's "
            "length unit: by default the run's test split on its own dataset, every simulation "
            "of another dataset."
        ),
    )
    p.add_argument("--run", required=True, metavar="DIR", help="training run or ensemble folder")
    p.add_argument("--dataset", required=True, metavar="FILE", help="dataset .h5 file")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--sim", action="append", metavar="NAME",
                   help="simulation to roll out (repeatable; default: see --split)")
    p.add_argument("--split", choices=("train", "val", "test", "all"),
                   help="the run's split to roll out (default: test on the run's own dataset, "
                   "all simulations of another dataset)")
    p.add_argument("--checkpoint", default="best", choices=("best", "last"))
    p.add_argument("--skip", type=NN_INT, help="skipped frames (default: the dataset's "
                   "skip_frames attribute)")
    p.add_argument("--steps", type=POS_INT, help="rollout steps (default: to the last frame)")
    p.add_argument("--nodes", type=POS_INT, help="fixed seeded node subset (the study: 2048 on "
                   "ClotEntry; default: the run's nodes_per_sample, else all nodes)")
    p.add_argument("--seed", type=NN_INT, default=0, help="seed of the node subset")
    p.add_argument("--format", default="xdmf", choices=("xdmf", "vtu"), help="ParaView format")
    p.add_argument("--no-gif", action="store_true", help="skip the animation")
    p.add_argument("--no-guards", action="store_true", help="roll the model out alone: no "
                   "containment in the vessel, no clot coherence (default: guards on, their "
                   "corrections reported)")
    p.add_argument("--centring", type=auto_radii, metavar="R", help="also the centring guard: "
                   "the whole clot moved rigidly to within R vessel radii of the middle of the "
                   "vessel's cross-section; 'auto': R that leaves 95%% of the run's training "
                   "clots alone (default: off)")
    p.add_argument("--coherence-tolerance", type=auto_radii, metavar="R", dest="coherence",
                   help="the coherence guard's tolerance: the part of a clot node's deviation "
                   "from a rigid copy of the start frame beyond R vessel radii is pulled back; "
                   "'auto': R that leaves 95%% of the run's training clots' nodes and frames "
                   "alone (0.21 r on BendVessel, 0.38 r on ClotEntry; their true clots stray "
                   "up to 0.5 and 1.3 r). Default: auto when the run's dataset is there, "
                   "else 1, with a warning")
    p.add_argument("--coherence-stretch", type=float_at_least(1.0), metavar="S",
                   help="the coherence guard's copy of the start frame may also stretch, "
                   "keeping its volume, by principal stretches up to S (and down to 1/S), so a "
                   "clot that shortens and widens as it leaves the vessel is not pulled back to "
                   "its shape inside it; 'auto' tolerance is then fitted to that copy (default: "
                   "a rigid copy)")
    p.add_argument("--keep-wall-velocity", action="store_true",
                   help="the step after containment reads the clot's velocity from before it: a "
                   "node put back inside the vessel keeps moving as the learned step moved it, "
                   "instead of losing the motion containment took out (default: it loses it)")
    p.add_argument("--centre-pull", type=NN_FLOAT, metavar="K", help="(a run trained with "
                   "--follow-axis) the prior's centring pull at strength K in (0, 1], set at "
                   "rollout time, in the single steps too (default: the run's own, if any)")
    p.add_argument("--centre-tolerance", type=auto_radii, metavar="R", help="--centre-pull's "
                   "tolerance in vessel radii; 'auto' (default): the run's training clots' median")
    p.add_argument("--rotations", type=NN_INT, default=0, metavar="R",
                   help="a rotation ensemble: roll the model (every member of an ensemble) "
                   "out on R copies of each simulation, the first unturned, R - 1 turned by "
                   "fixed random rotations, each turned back and all averaged; the spread is "
                   "reported as for an ensemble (default 0: off)")
    output_flags(p, "replace existing rollout files in DIR")
    p.set_defaults(func=_run_rollout)


def _run_rollout(args) -> int:
    from thrombojax.eval.report import rollout_run

    res = rollout_run(args.run, args.dataset, args.out, simulations=args.sim, split=args.split,
                      which=args.checkpoint, skip=args.skip, n_steps=args.steps,
                      n_nodes=args.nodes, seed=args.seed, format=args.format,
                      gif=not args.no_gif, force=args.force, progress=not args.quiet,
                      guards=not args.no_guards, rotations=args.rotations, centring_r=args.centring,
                      coherence_r=args.coherence, coherence_stretch=args.coherence_stretch,
                      keep_wall_velocity=args.keep_wall_velocity, centre_pull=args.centre_pull,
                      centre_tolerance=args.centre_tolerance)
    print(f"simulations: {res['selection']['how']}")
    print(res["table"], end="")
    print(f"wrote rollouts to {args.out}/")
    return 0


REGISTRARS = [_add_evaluate, _add_rollout]
