"""The ``train`` subcommand: its flags (each a :class:`thrombojax.train.config.TrainConfig` field
of the same name, or a run-level option) and the call into :func:`thrombojax.train.loop.train`."""

from __future__ import annotations

import dataclasses

from thrombojax.cli.options import (
    NN_FLOAT,
    NN_INT,
    POS_FLOAT,
    POS_INT,
    angle,
    auto_radii,
    output_flags,
)

__all__ = ["REGISTRARS"]


def _add_train(sub) -> None:
    p = sub.add_parser(
        "train",
        help="train a surrogate (MeshGraphNet, Transolver, Erwin) on a dataset",
        description=(
            "Train a step-by-step surrogate: AdamW with linear warm-up then cosine decay, "
            "masked MSE on clot nodes, random rotations, optional node subsampling and "
            "BaryCentricSampling, and by default the outlet recipe on top (--recipe: the "
            "step moves the clot along the vessel's axis and learns the rest from its "
            "velocity along and across that axis, the nearby wall, the clot's room in the "
            "vessel and where it stands against the vessel's open end, under random-walk and "
            "speed noise; '--recipe "
            "rollout' a k-step loss with push-forward instead; '--recipe study' trains as the "
            "study did). Writes DIR/config.json, DIR/checkpoints/{best,last}, "
            "DIR/metrics.jsonl and DIR/loss.png. Options left out take the recipe's, the "
            "--config file's, else the study's values (each model's batch size and learning "
            "rate)."
        ),
    )
    p.add_argument("--dataset", metavar="FILE", help="dataset .h5 file (default: the dataset of "
                   "a run's config.json given as --config)")
    p.add_argument("--model", help="mgn | transolver | erwin (default: the model of a run's "
                   "config.json given as --config)")
    p.add_argument("--out", required=True, metavar="DIR", help="run directory to write")
    p.add_argument("--config", metavar="FILE", help="JSON training config (TrainConfig keys), "
                   "or a run's config.json to repeat that run")
    p.add_argument("--resume", action="store_true", help="continue the run in DIR exactly")
    p.add_argument("--epochs", type=POS_INT, help="epochs (study: 300)")
    p.add_argument("--batch-size", type=POS_INT, help="samples per step (study: 8 mgn/erwin, 16 "
                   "transolver); a multiple of the number of devices")
    p.add_argument("--lr", type=POS_FLOAT,
                   help="peak learning rate (study: 1e-3 mgn, 1e-4 others)")
    p.add_argument("--warmup-epochs", type=NN_FLOAT, help="linear warm-up epochs (study: 10)")
    p.add_argument("--radius", type=POS_FLOAT, help="graph radius in scaled coordinates (a "
                   "model config field)")
    p.add_argument("--max-rotation", type=angle, help="largest random rotation, radians; also "
                   "'pi', 'pi/2', '0.5pi' or '90deg' (study's best: pi; 0 disables)")
    p.add_argument("--uniform-rotation", action="store_true", default=None, help="draw the "
                   "rotation's angle from the uniform measure on rotations (with "
                   "--max-rotation pi every orientation equally likely; default: an angle "
                   "uniform in [0, max], which turns a window by < 45 degrees a quarter of the "
                   "time)")
    p.add_argument("--nodes-per-sample", type=POS_INT, help="subsample N nodes per sample, clot "
                   "fraction kept (study: 2048 on ClotEntry; default all nodes)")
    p.add_argument("--bary-ratio", type=NN_FLOAT, help="BaryCentricSampling samples per real "
                   "sample (study's best on BendVessel: 2, i.e. real:generated 1:2; default 0)")
    p.add_argument("--noise-std", type=NN_FLOAT, help="training noise on s_t, in vessel radii "
                   "(learning-to-simulate / MeshGraphNets noise)")
    p.add_argument("--noise-gamma", type=NN_FLOAT, help="share of the noise the model learns to "
                   "remove from the next position (default 0.1)")
    p.add_argument("--noise-walk", action="store_true", default=None, help="with --history "
                   "H > 1: the noise is a random walk over all H input velocities "
                   "(learning-to-simulate's), not on the current frame alone")
    p.add_argument("--noise-shared", type=NN_FLOAT, help="share (0-1) of the noise variance "
                   "common to all clot nodes of a window: teaches the model that the whole "
                   "clot's recent motion can be wrong, as in a rollout (default 0)")
    p.add_argument("--wall-noise", type=NN_FLOAT, help="wall noise, in vessel radii: clot nodes "
                   "within this distance of the wall are moved through it (half of them, to a "
                   "depth of this times |N(0,1)|) in every input frame and by half as much in the "
                   "targets, so the model learns to bring a node that crossed the wall back; "
                   "use with --wall-features C --wall-signed (default 0: off)")
    p.add_argument("--history-noise", type=NN_FLOAT, help="history noise, in vessel radii: "
                   "with --history H >= 2, the whole clot is shifted by one N(0, this^2) vector "
                   "in the frames before s_{t-1} (s_t, its velocity and the target unchanged), so "
                   "the model does not carry a clot-wide acceleration over from its history, "
                   "which in a rollout speeds the clot up step after step (default 0: off)")
    p.add_argument("--speed-noise", type=NN_FLOAT, help="speed noise, a fraction: the clot's "
                   "input motion scaled by 1 + N(0, this^2) per window (s_t and the target "
                   "unchanged): the model sees a clot too fast or too slow (default 0: off)")
    p.add_argument("--speed-noise-steady", type=NN_FLOAT, help="with --speed-noise: noise only "
                   "windows whose clot keeps its speed to s_t+1 within this fraction (0: all)")
    p.add_argument("--direction-noise", type=NN_FLOAT, help="direction noise, radians: the "
                   "clot's input motion turned by one random rotation per window (angle vector "
                   "N(0, this^2) per axis; s_t and the target unchanged): the model is shown a "
                   "clot coming in from off its path and the true next frame (default 0: off)")
    p.add_argument("--swell-noise", type=NN_FLOAT, help="swell noise, a fraction: the clot of "
                   "the input frames scaled about its centroid by 1 + N(0, this^2), one draw per "
                   "window (with a random rate over the input frames), the target by half as "
                   "much: the model learns to take back a swelling of the clot, which rollouts "
                   "otherwise keep and grow (default 0: off)")
    p.add_argument("--stretch-noise", type=NN_FLOAT, help="stretch noise, a fraction: as "
                   "--swell-noise along the clot's motion only (its front moved ahead of its "
                   "rear), which rollouts' clots otherwise keep and grow (default 0: off)")
    p.add_argument("--time-scale", type=float, help="time-scaling augmentation, the largest "
                   "factor F >= 1: each window's clot motion played F^u times as fast, u ~ "
                   "U(-1, 1) (velocities k, accelerations k^2 times), so a dataset at another "
                   "frame rate, or a clot driven faster, is within the training speeds "
                   "(default 1: off)")
    p.add_argument("--clot-mean-weight", type=NN_FLOAT, help="extra weight of the clot-wide "
                   "error in the loss: the squared error of the clot's mean (normalised) "
                   "acceleration counted this many times more, so the model is fitted first "
                   "where a rollout's end position comes from, the motion of the clot as a "
                   "whole (default 0: off, the plain per-node MSE)")
    p.add_argument("--wall-loss-weight", type=NN_FLOAT, help="weight of the wall term in the "
                   "loss: the squared distance by which a predicted clot node lies further "
                   "through the vessel wall than the true one (in units of the normalised "
                   "error), so the model pays more for an outward error than an inward one "
                   "(docs/rollouts.md has what it measured; default 0: off)")
    p.add_argument("--speedup-weight", type=NN_FLOAT, metavar="W", help="extra loss weight of "
                   "the training windows whose true clot speeds up (as where it leaves the "
                   "vessel): each such window weighs 1 + W (default 0: off)")
    p.add_argument("--speedup-fraction", type=NN_FLOAT, metavar="F", help="with "
                   "--speedup-weight: a window speeds up where its clot moves faster into "
                   "s_t+1 than 1 + F times its speed into s_t (default 0.1)")
    p.add_argument("--average-weights", type=NN_FLOAT, metavar="SHARE", help="weight "
                   "averaging: the model is the mean of the weights after each of the last "
                   "SHARE (0-1) of the training steps (stochastic weight averaging over the "
                   "tail of the learning-rate decay); validation and checkpoints use the mean "
                   "(default 0: off, the last weights)")
    p.add_argument("--seed", type=NN_INT, help="seed of initialisation, data order, augmentations")
    p.add_argument("--skip-frames", type=NN_INT, help="first frames never used as frame t of a "
                   "window (default 0: every window)")
    p.add_argument("--rollout-steps", type=POS_INT, help="k of the k-step unrolled loss "
                   "(default 1: single-step loss)")
    p.add_argument("--pushforward-steps", type=NN_INT, help="steps applied without gradients "
                   "before the loss steps (push-forward training; default 0)")
    p.add_argument("--pushforward-guards", action="store_true", default=None, help="pass every "
                   "push-forward step's prediction through the rollout's coherence and "
                   "containment guards before the next step reads it, so the loss starts from "
                   "the state a guarded rollout is in (needs --pushforward-steps >= 1)")
    p.add_argument("--input-guards", action="store_true", default=None, help="pass every "
                   "training window's input frames (after the noise) through the rollout's "
                   "coherence and containment guards, the target still the true next frame")
    p.add_argument("--guard-coherence", type=NN_FLOAT, metavar="R", help="with "
                   "--pushforward-guards or --input-guards: coherence's tolerance in vessel "
                   "radii (default 0.2)")
    p.add_argument("--members", type=POS_INT, default=1, help="train an ensemble of M members "
                   "differing only by seed into DIR/member_<i> (rollouts then report spread)")
    p.add_argument("--curriculum-epochs", type=NN_FLOAT, help="grow k from 1 to "
                   "--rollout-steps over this many epochs (default 0: k from the start)")
    # the names of thrombojax.train.recipes.RECIPES (not imported here: it loads jax; a test
    # keeps the two equal)
    p.add_argument("--recipe", choices=("axis", "rollout", "history", "robust", "room",
                                        "outlet", "study"), help="a named set of "
                   "training options under the explicit ones: 'outlet' (the default without "
                   "--config or --resume: 'room' plus the outlet features, --outlet-features "
                   "2, so the clot speeds up as it leaves the vessel; on BendVessel's held-out "
                   "simulations 0.76-0.94 r off at the end where 'room' is 1.62-2.24 r, on "
                   "ClotEntry within room's seed-to-seed spread; its one step is worse than "
                   "constant velocity; at most 8,192 nodes per sample), 'room' ('axis' "
                   "without the history frame, plus the vessel-following prior, wall features "
                   "at 0.5 r with the clot-wide room, the clot-wide error weighted 10x, speed "
                   "noise 0.3, --select-by last; the default before), 'axis' ('history' plus "
                   "the velocity split along and across the local vessel axis, --axis-features "
                   "2; the best one step), 'history' (the step "
                   "also reads the acceleration before t, "
                   "--history 2, single-step loss, random-walk noise 0.01 r, rotations up to "
                   "pi), 'rollout' (noise "
                   "0.01 r, 1 push-forward step, a 3-step loss grown over 6 epochs, rotations "
                   "up to pi; four times the cost per epoch), 'robust' (history plus wall "
                   "noise 0.1 r with signed wall features, history noise 0.02 r, speed and "
                   "direction noise 0.1, --select-by last: better than history on BendVessel, "
                   "worse on ClotEntry) or 'study' (the study's "
                   "single-step recipe, TrainConfig's defaults)")
    p.add_argument("--frame", choices=("global", "vessel"), help="frame of the learned step: "
                   "'vessel' works in the rigid vessel's principal axes (invariant to the "
                   "vessel's orientation); default 'global'")
    p.add_argument("--history", type=POS_INT, help="frames before t the learned step reads: "
                   "1 (default) the velocity alone; H >= 2 also the H - 1 accelerations before "
                   "t (they show the drive and damping that the velocity does not)")
    p.add_argument("--stop-history-gradient", action="store_true", default=None,
                   help="with --history H > 1 and --rollout-steps K > 1: no gradient through "
                   "the history features in the unrolled loss")
    p.add_argument("--wall-features", type=NN_FLOAT, help="give clot nodes the distance and "
                   "direction to the nearest vessel node, cut off at this many vessel radii "
                   "(default 0: off)")
    p.add_argument("--axis-features", type=NN_FLOAT, help="give clot nodes their velocity "
                   "split along and across the local vessel axis (from the wall's normals "
                   "within about this many vessel radii; default 0: off)")
    p.add_argument("--follow-axis", type=NN_FLOAT, help="the step's prior moves each clot "
                   "node along the vessel at its current speed (axis from the wall's normals "
                   "within about this many vessel radii) and the model learns the rest "
                   "(default 0: the prior is constant velocity)")
    p.add_argument("--lateral-hold", type=NN_FLOAT, help="take the clot-wide mean of the "
                   "model's acceleration across the vessel's axis out of every step (axis "
                   "from the wall's normals within about this many vessel radii), so the clot "
                   "moves sideways only as the vessel turns and as it deforms (default 0: off)")
    p.add_argument("--outlet-features", type=NN_FLOAT, help="tell clot nodes where the clot "
                   "is against the vessel's open ends, ahead of its motion (the vessel nodes "
                   "within about this many radii lie behind a node nearing the outlet), per "
                   "node and clot-wide, so the step sees the outlet coming (default 0: off)")
    p.add_argument("--shape-features", type=NN_FLOAT, help="tell clot nodes their place "
                   "along the clot's motion and the clot's length and width, over this many "
                   "radii, so the step sees a stretched clot (default 0: off)")
    p.add_argument("--clearance-features", type=NN_FLOAT, help="give clot nodes the distance "
                   "from the clot's centroid to the nearest vessel node, over this many radii "
                   "(the vessel's width where the clot stands; default 0: off)")
    p.add_argument("--section-features", type=NN_FLOAT, help="give clot nodes the width of "
                   "the vessel's cross-section at the clot's centroid, over this many radii "
                   "(the width that sets the clot's speed, unchanged when the clot drifts "
                   "across the vessel; default 0: off)")
    p.add_argument("--centre-pull", type=NN_FLOAT, help="with --follow-axis: the share (at "
                   "most 1) of the clot centroid's offset from the middle of the vessel's "
                   "cross-section that the prior takes back every step, turning its velocities "
                   "toward the middle at their speed (default 0: off)")
    p.add_argument("--centre-tolerance", type=auto_radii, metavar="R", help="with "
                   "--centre-pull: the centroid's offset from the middle, in vessel radii, left "
                   "alone; 'auto': the median of the true clots' offsets over the training "
                   "simulations' frames (default 0)")
    p.add_argument("--rest-edges", action="store_true", default=None, help="meshgraphnet: "
                   "give clot-clot edges their displacement in the clot's rest state (the "
                   "simulation's first frame) beside the current one, so the step sees strain")
    p.add_argument("--start-speed", action="store_true", default=None, help="the step also "
                   "reads the clot's start speed: its speed in the true frames a rollout starts "
                   "from (the dataset's skip_frames in training), kept for the whole rollout, so "
                   "the step knows the simulation's speed without carrying its own errors")
    p.add_argument("--start-speed-noise", type=NN_FLOAT, metavar="F", help="with "
                   "--start-speed: every training window's start speed scaled by 1 + e, "
                   "e ~ N(0, F^2), so the step cannot tell its training simulations apart by it "
                   "(a fraction; default 0: off)")
    p.add_argument("--start-span", type=int, metavar="K", help="with --start-speed: the start "
                   "speed is the clot's mean speed over the K frames up to the rollout's start "
                   "(frames before 0: the clot at rest); the start frame K (e.g. 5 on "
                   "BendVessel) gives its travel from rest, which tells how soon it broke free "
                   "(default 1: the speed into the start frame)")
    p.add_argument("--wall-signed", action="store_true", default=None, help="with "
                   "--wall-features: the features are the signed distance to the wall "
                   "(positive outside) and its outward normal, which tell a node that crossed "
                   "the wall from one inside it")
    p.add_argument("--wall-clot-mean", action="store_true", default=None, help="with "
                   "--wall-features: every clot node also gets the clot-wide mean of the wall "
                   "distance, the room the whole clot has (its speed follows the vessel's width)")
    p.add_argument("--select-by", choices=("mse", "rollout", "last"), help="what picks the "
                   "best checkpoint: 'mse' (the study's: the lowest one-step validation MSE), "
                   "'rollout' (each epoch also rolls the model out alone on every validation "
                   "simulation, logged as val_rollout_* with its ratio to constant velocity; "
                   "the lowest full-length rollout MSE) or 'last' (the last epoch's, at the end "
                   "of the learning-rate decay)")
    p.add_argument("--init-from", metavar="RUN", help="start from the weights of RUN (a run "
                   "of the same model and step inputs; fine-tuning, e.g. with --rollout-steps)")
    p.add_argument("--init-checkpoint", dest="init_which", choices=("best", "last"),
                   help="which checkpoint of --init-from (default best)")
    p.add_argument("--n-val", type=NN_INT, help="validation simulations (default 2)")
    p.add_argument("--n-test", type=NN_INT, help="test simulations, never trained on (default 1)")
    p.add_argument("--tiny", action="store_true", default=None, help="tiny model config")
    p.add_argument("--distributed", action="store_true",
                   help="multi-host: call jax.distributed.initialize() first (run on every host)")
    output_flags(p, "start a new run in DIR even if it holds one (its checkpoints are removed)")
    p.set_defaults(func=_run_train)


def _run_train(args) -> int:
    from thrombojax.train.config import RunConfig, TrainConfig, load_config_file
    from thrombojax.train.loop import train

    names = [f.name for f in dataclasses.fields(TrainConfig) if hasattr(args, f.name)]
    overrides = {k: getattr(args, k) for k in names if getattr(args, k) is not None}
    from thrombojax.train.recipes import DEFAULT_RECIPE, recipe

    implicit = None if (args.config or args.resume) else DEFAULT_RECIPE
    chosen = args.recipe if args.recipe is not None else implicit
    if chosen is not None:
        overrides = {**recipe(chosen), **overrides}
    config = load_config_file(args.config) if args.config else None
    if args.radius is not None:
        base = config.train if isinstance(config, RunConfig) else (config or TrainConfig())
        overrides["model_config"] = {**base.model_config, "radius": args.radius}
    from thrombojax.train.summary import run_summary

    if args.members > 1:  # an ensemble: members differ only by seed (seed + i)
        from thrombojax.train.ensemble import train_ensemble

        seed = overrides.pop("seed", 0)
        ens = train_ensemble(args.dataset, args.model, args.out, args.members, seed=seed,
                             resume=args.resume, config=config, progress=not args.quiet,
                             force=args.force, **overrides)
        print(f"trained an ensemble of {ens.n_members} {ens.model.name} members (seeds "
              f"{ens.seeds}) in {args.out}/; roll it out with 'thrombojax rollout --run "
              f"{args.out}'")
        return 0
    trained = train(args.dataset, args.model, args.out, config=config, resume=args.resume,
                    progress=not args.quiet, distributed=args.distributed, force=args.force,
                    **overrides)
    print(run_summary(args.out, trained.model.name))
    return 0


REGISTRARS = [_add_train]
