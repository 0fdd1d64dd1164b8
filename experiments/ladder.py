"""The stability ladder: one small model, one CPU budget per rung, each rung adds one technique.

    python experiments/ladder.py --dataset data/bendvessel.h5 --out experiments/results/ladder
    python experiments/ladder.py --dataset data/clotentry.h5 --nodes 2048 --epochs 4
        --out experiments/results/ladder_clotentry --rungs baseline,rotation --title ClotEntry
        --test clotentry_008,clotentry_009 --val clotentry_007     # (one command)

Rungs (cumulative): baseline (single-step loss) -> + input noise -> + push-forward ->
+ k-step loss with a curriculum -> + guards in the rollout (same model) -> + rotation
augmentation; then rotation handled by the frame instead: the k-step rung with guards in the
rigid vessel's frame (exactly invariant to orientation, no augmentation) -> the same with
gradient clipping (global norm 1); and the rotation rung + wall features (distance and
direction to the nearest vessel node, cut off at 1.5 vessel radii); and an ensemble of three
models of the rotation rung's recipe (member 0 is that rung's model, members 1-2 the same
recipe, epochs and seeds 1-2), rolled out together with guards, whose mean is the prediction
and whose spread is scored against the error (``thrombojax.eval.uncertainty``); and the
rotation rung's recipe with a history of two frames (the step also reads the acceleration
before t, ``thrombojax.simulator.step``), the same with a 3x smaller learning rate, and the
history with the single-step loss (noise and rotations, no push-forward or k-step), the same
reading three frames, an ensemble of three of it, and it with
the noise as a random walk over all input frames (``noise_walk``), and an ensemble of three
of that; the same with one push-forward step (no k-step gradients); and the rotation rung's
k-step recipe with the history, its random-walk noise and no gradient through the history
features (``stop_history_gradient``); and the random-walk rung with half of the noise's
variance common to all clot nodes of a window (``noise_shared``), with an ensemble of three of
it (its seed spread); and the random-walk rung with three times the noise (0.03 r), with an
ensemble of three; and the random-walk rung with wall features (``walk_wall``); the
random-walk rung's model with the guards off (``walk_alone``), and the random-walk rung trained
with wall noise (``walk_wallnoise``, clot nodes moved through the wall in the input frames, the
targets by half as much, ``thrombojax.train.noise.add_wall_noise``), rolled out alone and with
the guards (``wallnoise_guards``), and it with signed wall features (the signed distance to the
wall and its normal), alone and with the guards (``wallnoise_signed``, ``signed_guards``), a
second seed of it and the two as an ensemble, alone (``signed_seeds``), the signed features
without the wall noise (``signed_alone``) and with twice the wall noise (``wallnoise2_signed``),
alone; and it with history noise (``history_noise``: the clot shifted in the frames before
s_{t-1}, so the model does not carry the history's clot-wide acceleration over), alone
(``signed_histnoise``), its seeds (``histnoise_seeds``), with the guards
(``histnoise_guards``), and it with half of the noise's variance common to the clot, alone
(``histnoise_shared``, ``histshared_seeds``); and it with speed noise (``speed_noise``: the
clot's input motion scaled by one random factor, the target unchanged, so the model is shown a
clot off its speed; ``thrombojax.train.noise.add_speed_noise``) of 3 % and 10 %, alone
(``speed03``, ``speed10``), two seeds of the first (``speed03_seeds``) and with the guards
(``speed03_guards``, ``speed10_guards``); and it with time scaling (``time_scale`` 1.5: each
window's clot motion played up to 1.5 times faster or slower, so speeds beyond the data's are
trained; ``thrombojax.train.noise.time_scale_window``), alone and guarded (``tscale``,
``tscale_guards``); and it with direction noise (``direction_noise`` 0.1 rad: the clot's input
motion turned by one random rotation, the target unchanged, so the model is shown a clot coming
in across its path; ``thrombojax.train.noise.add_direction_noise``), alone and guarded
(``direction10``, ``direction10_guards``), with the speed noise 0.1 as well (``dirspeed``,
``dirspeed_guards``, two seeds ``dirspeed_seeds``) and with 0.3 rad (``dirspeed3``); and which
checkpoint is kept: direction and speed noise without the history noise, picking its best
checkpoint by a rollout on the validation simulation each epoch (``select_by`` ``rollout``:
``nohist_rollout``, guarded ``nohist_rollout_guards``, four seeds ``nohist_rollout_seeds``),
the last epoch's checkpoint of the same trainings (a rung's ``checkpoint`` ``last``:
``nohist_last``, ``nohist_last_guards``, ``nohist_last_seeds``) and of the history-noise
recipe (``histnoise_last``, ``histnoise_last_seeds``); the last checkpoints of ``dirspeed``
(``dirspeed_last``, guarded ``dirspeed_last_guards``, five seeds alone and as an ensemble
``dirspeed_last_seeds``, the ensemble guarded ``dirspeed_last_ens_guards``), and the same
recipe trained with ``--select-by last`` (``robust``, ``robust_guards``: the ``robust``
recipe of ``thrombojax train``; ``robust_nohist_guards`` without its history noise); the
default recipe with the velocity split along and across the local vessel axis
(``--axis-features 2``: ``walk_axis`` guarded, ``axis_alone`` the same model unguarded,
``axis_wall`` / ``axis_wall_guards`` / ``axis_wall_seeds`` it with the wall term in the loss
weighted 10x (``--wall-loss-weight``, alone, guarded, seeds 0 and 1 alone), ``axis_wall1`` /
``axis_wall1_seeds`` weighted 1x,
``axis_seeds`` / ``axis_ens_guards`` seeds 0 and 1 alone and guarded, each also scored alone;
``axis_ens3_guards`` seeds 0-2 guarded; ``walk_ens2_guards`` the control, the default
recipe without the split, seeds 0 and 1 guarded; ``axis_signed`` / ``axis_signed_guards``
the split with the wall noise and signed wall features of ``wallnoise_signed``;
``axis_committee`` / ``axis_committee_guards`` / ``axis_committee3_guards`` its seeds rolled
out as a committee, the members' mean step fed back, alone and guarded; ``axis_swell`` /
``axis_swell10`` (and ``*_guards``) the split with swell noise of 5 % and 10 %
(``thrombojax.train.shape_noise``), ``axis_swell03_last*`` it with 3 % (the last checkpoint,
alone and guarded), ``axis_swell_last*`` / ``axis_swell10_last*`` their last
checkpoints (``*_seeds`` / ``*_ens_guards`` seeds 0-1, ``*_seeds3`` / ``*_ens3_guards`` seeds
0-2, ``*_seeds5`` / ``*_ens5_guards`` seeds 0-4, ``axis_swell10_last_committee5`` the five as a
committee alone; ``axis_swell10_wall3*`` it with the wall term weighted 3x, the last
checkpoint, seed 0 and seeds 0-1, alone and guarded; ``axis_swell10_last_rot4*`` /
``*_rot8`` / ``*_seeds_rot4`` its last checkpoint as a rotation ensemble, each model also on 3
or 7 rotated copies of every simulation, turned back and averaged
(``thrombojax.simulator.rotations``); ``axis_swell10_haar*`` it trained with uniformly random
orientations (``--uniform-rotation``), seed 0 and seeds 0-1, alone, guarded and as a rotation
ensemble), ``axis_signed_swell10*`` it with the
wall noise and signed wall features (``*_last*`` its last checkpoint); ``follow`` /
``follow_alone`` the split with the vessel-following prior, guarded and alone;
``follow_nohist*`` the prior without the history frame, ``follow_histnoise*`` with history
noise, ``follow_steady*`` without the history frame and trained only on the frames rollouts
run on, from the dataset's ``skip_frames``); ``axis_swell10_cm_last*`` the 10 % swell noise
and ``follow_nohist_cm_last*`` the prior without the history frame, each with the clot-wide
error weighted 10x (``--clot-mean-weight``; the last checkpoint, alone and guarded;
``follow_nohist_cm_last_ens3_guards`` / ``follow_nohist_cm_last_seeds3`` its seeds 0-2,
guarded and alone, each member also scored alone); ``follow_hold_last*`` the latter with the
lateral hold (``--lateral-hold 2``: the clot-wide mean of the model's acceleration across the
vessel's axis taken out of every step), with the same seeds, alone and guarded;
``follow_kstep_last*`` / ``follow_kstep6_last*`` it with the k-step loss instead (3 steps after
one push-forward step; 6 steps), the same variants; ``follow_speed_last*`` it with speed noise
0.1 and wall features (0.5 r) instead, the same variants.
``--transfer DATA`` also rolls every rung out on all simulations of another
dataset (train on one, evaluate on the other). Every rung trains the same small MeshGraphNet
(``--size study``: the study's, for an accelerator) for the same wall-clock budget (the epoch
count is calibrated on this machine by timing one epoch), or for ``--epochs`` epochs, then is
measured on held-out simulations (the split is by name: the last rotation is outside the
training range):

- single-step MSE over all windows and over the rollout phase (frames >= the dataset's
  ``skip_frames``), as a ratio to constant velocity (CV);
- a rollout from ``skip_frames`` to the last frame: MSE@10, MSE@full (in vessel radii squared
  and as a ratio to CV), the final clot-centroid error (radii), the largest share of clot nodes
  outside the vessel (``thrombojax.eval.metrics``), and the guards' largest correction; each
  rung's ``result.json`` also keeps, per simulation and step, the MSE (model and CV), the share
  of clot nodes outside, the centroid error and the centroid's speed (model and truth, radii
  per frame), the centroid error split along and across the true clot's track and the clot's
  size against the truth's (``thrombojax.eval.track``; also at the last frame), and for a
  single model with a history its history gain (``thrombojax.eval.drift``: the share of a
  change of the history's acceleration it carries over, mean over the rollout's frames) and
  for every single model its speed carry (the share of a 5 % clot-wide speed error in its
  inputs that it keeps: 1 for constant velocity) and direction carry (the share of a 0.1 rad
  sideways turn of its input motion it keeps).

Resumable: a rung whose ``result.json`` exists is skipped; a rung whose training was killed
resumes from its last checkpoint. Writes ``table.md``, ``ladder.json`` and
``error_per_step.png`` with the command, device, versions, date and machine load
(``experiments/ladder_report.py``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import shutil
import sys
import time

from thrombojax import study
from thrombojax.cli import allocator
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text
from thrombojax.train.loop import train
from thrombojax.train.state import latest_step

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # the sibling modules
from ladder_eval import evaluate_runs, members_alone  # noqa: E402
from ladder_report import write_reports  # noqa: E402
from ladder_rungs import (  # noqa: E402
    COMMON,
    RUNGS,
    SMALL_MGN,  # noqa: F401  (the ladder's small model, for its users)
    STUDY_SIZE,
    Rung,
)

# the held-out and validation simulations of BendVessel (``--test``, ``--val`` defaults):
# rotations 50, 120 and 190 degrees (190 outside the training rotations), and 90
DEFAULT_TEST = ("bendvessel_005", "bendvessel_012", "bendvessel_019")
DEFAULT_VAL = ("bendvessel_009",)


def _train_rung(rung: Rung, data: str, folder: pathlib.Path, split: dict, minutes: float,
                max_epochs: int, epochs: int | None = None,
                n_nodes: int | None = None, common: dict = COMMON) -> pathlib.Path:
    run = folder / "run"
    cfg = {**common, **rung.train, **split, "nodes_per_sample": n_nodes}
    if cfg.get("skip_frames") == "dataset":  # train on the frames rollouts run on only
        cfg["skip_frames"] = study.skip_frames(open_dataset(data))
    if latest_step(run / "checkpoints" / "last") is not None:
        info = json.loads((run / "config.json").read_text())
        if latest_step(run / "checkpoints" / "best") is not None and \
                _finished(run, info["total_steps"]):
            return run
        train(data, "mgn", run, resume=True, progress=False)
        return run
    if epochs is not None:
        print(f"  {rung.name}: {epochs} epochs (fixed)", flush=True)
        train(data, "mgn", run, epochs=epochs, progress=False, **cfg)
        return run
    calib = folder / "calibration"
    stamps: list[float] = []
    # timed at the rung's full k (no curriculum): an epoch of the k-step loss costs about k
    # single-step epochs, so timing the curriculum's first (k = 1) epoch overran the budget
    train(data, "mgn", calib, epochs=1, progress=False, force=True,
          callback=lambda step, m: stamps.append(time.perf_counter()),
          **{**cfg, "curriculum_epochs": 0})
    shutil.rmtree(calib)
    epoch_s = (stamps[-1] - stamps[0]) / max(len(stamps) - 1, 1) * len(stamps)
    epochs = int(min(max(minutes * 60 // max(epoch_s, 1e-9), 2), max_epochs))
    print(f"  {rung.name}: {epoch_s:.1f} s per epoch -> {epochs} epochs", flush=True)
    train(data, "mgn", run, epochs=epochs, progress=False, **cfg)
    return run


def _finished(run: pathlib.Path, total_steps: int) -> bool:
    lines = (run / "metrics.jsonl").read_text().splitlines()
    return any(json.loads(ln).get("step") == total_steps for ln in lines if ln.strip())


def _member_folder(rung: Rung, out: pathlib.Path, seed: int) -> pathlib.Path:
    """Where member ``seed`` of an ensemble rung is trained. Members of rungs that reuse the
    same rung with the same recipe are the same trainings, so they live beside the reused
    rung (``out/<reused>/member_<seed>``) and are trained once, whichever rung asks first;
    a rung whose recipe differs from the reused rung's keeps its own
    (``out/<rung>/member_<seed>``), as does a member an earlier ladder trained there."""
    own = out / rung.name / f"member_{seed}"
    base = next((r for r in RUNGS if r.name == rung.reuse), None)
    if (own / "run").exists() or base is None or base.train != rung.train:
        return own
    return out / base.name / f"member_{seed}"


def member_rung(rung: Rung, seed: int) -> Rung:
    """Member ``seed`` (>= 1) of an ensemble rung: the rung's recipe with that seed."""
    return dataclasses.replace(rung, name=f"{rung.name} member {seed}",
                               train={**rung.train, "seed": seed})


def train_seed(rung_name: str, out: pathlib.Path, seed: int, data: str, epochs: int,
               split: dict, n_nodes: int | None = None) -> pathlib.Path:
    """Train seed ``seed`` of rung ``rung_name`` for ``epochs`` epochs where the ladder
    evaluates it from, without evaluating it, so several seeds can train side by side before
    one ladder command evaluates them. Returns the run folder: ``out/<rung>/run`` for seed 0,
    ``<member folder>/run`` otherwise (``out/<rung or the rung it reuses>/member_<seed>/run``,
    ``_member_folder``)."""
    rung = next(r for r in RUNGS if r.name == rung_name)
    if seed:  # the ladder's own member recipe and folder
        folder = _member_folder(rung, out, seed)
        rung = member_rung(rung, seed)
    else:
        folder = out / rung.name
    folder.mkdir(parents=True, exist_ok=True)
    print("training", folder, epochs, "epochs", flush=True)
    return _train_rung(rung, data, folder, split, 0.0, epochs, epochs, n_nodes, COMMON)


def _member_runs(rung: Rung, out: pathlib.Path, data: str, split: dict,
                 n_nodes: int | None, common: dict = COMMON) -> list[pathlib.Path]:
    """The runs a rung evaluates: its own (or ``reuse``'s), plus for an ensemble members
    1 .. M-1 trained with the same recipe and epochs as member 0 and seeds 1 .. M-1 (in
    :func:`_member_folder`, shared by the rungs that reuse the same rung and recipe)."""
    first = out / rung.reuse / "run" if rung.reuse else out / rung.name / "run"
    if not (first / "config.json").is_file():
        raise SystemExit(f"ladder: rung {rung.name!r} needs rung {rung.reuse!r} trained first "
                         f"({first} has no run); add it to --rungs")
    runs = [first]
    epochs = json.loads((first / "config.json").read_text())["train"]["epochs"]
    for seed in range(1, rung.members):
        folder = _member_folder(rung, out, seed)
        folder.mkdir(parents=True, exist_ok=True)
        runs.append(_train_rung(member_rung(rung, seed), data, folder, split, 0.0, epochs,
                                epochs, n_nodes, common))
    return runs


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dataset", required=True, help="BendVessel dataset (.h5)")
    parser.add_argument("--out", required=True, help="results folder (resumable)")
    parser.add_argument("--minutes", type=float, default=6.0, help="training budget per rung")
    parser.add_argument("--max-epochs", type=int, default=200)
    parser.add_argument("--epochs", type=int, default=None,
                        help="a fixed epoch count per rung instead of the timed budget (the "
                        "same work per rung whatever else loads the machine)")
    parser.add_argument("--test", default=",".join(DEFAULT_TEST),
                        help="held-out simulations (comma-separated)")
    parser.add_argument("--val", default=",".join(DEFAULT_VAL), help="validation simulations")
    parser.add_argument("--rungs", default=",".join(r.name for r in RUNGS))
    parser.add_argument("--nodes", type=int, default=None,
                        help="train on and roll out a fixed subset of this many nodes (the "
                        "study's 2,048 for ClotEntry; default: all nodes)")
    parser.add_argument("--title", default="BendVessel", help="dataset label of the table")
    parser.add_argument("--size", choices=("small", "study"), default="small",
                        help="'small' (default): MeshGraphNet hidden 32, 5 blocks, batch 4, the "
                        "CPU ladder; 'study': the study's MeshGraphNet and batch 8 (accelerator)")
    parser.add_argument("--transfer", default=None, metavar="DATA",
                        help="also roll every rung's models out on every simulation of this "
                        "other dataset (train on --dataset, evaluate on DATA): "
                        "RUNG/transfer_<stem>.json and a table in OUT/transfer_<stem>/")
    args = parser.parse_args(argv)
    common = COMMON if args.size == "small" else STUDY_SIZE
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    split = {"test_sims": args.test.split(","), "val_sims": args.val.split(",")}
    wanted = args.rungs.split(",")
    results = {}
    for rung in RUNGS:
        if rung.name not in wanted:
            continue
        folder = out / rung.name
        done = folder / "result.json"
        if done.is_file():
            res = json.loads(done.read_text())
        else:
            folder.mkdir(exist_ok=True)
            t = time.perf_counter()
            if not rung.reuse:
                _train_rung(rung, args.dataset, folder, split, args.minutes, args.max_epochs,
                            args.epochs, args.nodes, common)
            runs = _member_runs(rung, out, args.dataset, split, args.nodes, common)
            res = evaluate_runs(runs, args.dataset, rung.guards, args.nodes,
                                which=rung.checkpoint, committee=rung.committee,
                                rotations=rung.rotations)
            res.update(rung=dataclasses.asdict(rung) | {"train": {k: str(v) for k, v in
                                                                   rung.train.items()}},
                       seconds=time.perf_counter() - t)
            print(f"  {rung.name}: MSE@full / CV = "
                  f"{res['mean']['mse_full'] / res['mean']['mse_full_cv']:.2f}", flush=True)
            # kept before the members are scored one by one, which a later run resumes
            atomic_write_text(done, json.dumps(res, indent=1))
        if rung.members > 1 and not rung.committee and "members_alone" not in res:
            runs = _member_runs(rung, out, args.dataset, split, args.nodes, common)
            res["members_alone"] = members_alone(runs, args.dataset, rung.guards, args.nodes,
                                                 rung.checkpoint, rung.rotations)
            atomic_write_text(done, json.dumps(res, indent=1))
        results[rung.name] = res
    table = write_reports(out, results, title=args.title, test_sims=split["test_sims"],
                          nodes=args.nodes)
    print(table)
    if args.transfer:
        print(_transfer(pathlib.Path(args.transfer), results, out, args, split, common))
    return 0


def _transfer(other: pathlib.Path, results: dict, out: pathlib.Path, args, split: dict,
              common: dict) -> str:
    """Evaluate every rung of ``results`` on all simulations of ``other`` (resumable: a rung's
    ``transfer_<stem>.json`` is reused) and write their table into ``out/transfer_<stem>/``."""
    names = list(open_dataset(other).names)
    rungs = {r.name: r for r in RUNGS}
    moved = {}
    for name in results:
        path = out / name / f"transfer_{other.stem}.json"
        if path.is_file():
            moved[name] = json.loads(path.read_text())
            continue
        runs = _member_runs(rungs[name], out, args.dataset, split, args.nodes, common)
        moved[name] = evaluate_runs(runs, str(other), rungs[name].guards, args.nodes, names,
                                rungs[name].checkpoint, rungs[name].committee,
                                rotations=rungs[name].rotations)
        atomic_write_text(path, json.dumps(moved[name], indent=1))
    folder = out / f"transfer_{other.stem}"
    folder.mkdir(exist_ok=True)
    return write_reports(folder, moved, title=f"{args.title} models on {other.name}",
                         test_sims=names, nodes=args.nodes)


if __name__ == "__main__":
    # its trainings under tcmalloc, as the thrombojax command's (docs/performance.md)
    allocator.reexec_script_with_tcmalloc(sys.argv[0], sys.argv[1:])
    sys.exit(main())
