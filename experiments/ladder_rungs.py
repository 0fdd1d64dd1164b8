"""The stability ladder's rungs: the training recipe, guards and reuse of each
(``experiments/ladder.py`` runs and measures them; its docstring says what each rung adds)."""

from __future__ import annotations

import dataclasses

import ladder_recipes
import numpy as np
from ladder_recipes import (  # noqa: F401  (COMMON, SMALL_MGN, STUDY_SIZE: for ladder.py)
    AXIS,
    AXIS_SIGNED,
    AXIS_SIGNED_SWELL10,
    AXIS_SWELL,
    AXIS_SWELL03,
    AXIS_SWELL10,
    AXIS_SWELL10_CM,
    AXIS_SWELL10_FRAME,
    AXIS_SWELL10_FRAME_SPEED,
    AXIS_SWELL10_FRAME_TSCALE,
    AXIS_SWELL10_FRAME_TSCALE2,
    AXIS_SWELL10_HAAR,
    AXIS_SWELL10_SPEED,
    AXIS_SWELL10_TSCALE,
    AXIS_SWELL10_WALL3,
    AXIS_WALL,
    AXIS_WALL1,
    COMMON,
    DIRECTION,
    DIRSPEED,
    DIRSPEED3,
    DIRSPEED_LAST,
    FOLLOW,
    FOLLOW_HISTNOISE,
    FOLLOW_HOLD,
    FOLLOW_KSTEP,
    FOLLOW_KSTEP6,
    FOLLOW_NOHIST,
    FOLLOW_NOHIST_CM,
    FOLLOW_NOHIST_CM_FRAME,
    FOLLOW_ROOM,
    FOLLOW_ROOM30,
    FOLLOW_ROOM30_OUTLET,
    FOLLOW_ROOM30_WIDE,
    FOLLOW_SHAPE30,
    FOLLOW_SPEED,
    FOLLOW_SPEED30,
    FOLLOW_SPEED50,
    FOLLOW_STEADY,
    HISTNOISE,
    HISTORY,
    NOHIST_ROLLOUT,
    NOISE,
    ROTATION,
    SIGNED,
    SMALL_MGN,
    SPEED03,
    SPEED10,
    STUDY_SIZE,
    TSCALE,
    WALK,
)

__all__ = ["Rung", "RUNGS", "last_alone_and_guarded"]


@dataclasses.dataclass(frozen=True)
class Rung:
    """One rung: training overrides, whether the rollout is guarded, which run it reuses."""

    name: str
    train: dict
    guards: bool = False
    reuse: str | None = None  # evaluate another rung's trained model
    members: int = 1  # > 1: a deep ensemble; member 0 is ``reuse``'s model, the others seeds 1..
    checkpoint: str = "best"  # which checkpoint of each run is evaluated ("best" or "last")
    committee: bool = False  # roll the members out as a committee (their mean step fed back)
    rotations: int = 0  # > 0: each model on that many copies (the first unturned), turned back


def last_alone_and_guarded(name: str, recipe: dict) -> tuple[Rung, Rung]:
    """Rung ``name`` (the recipe, its last checkpoint) and ``name_guards`` (the same model
    rolled out with the guards): the ladder's usual pair."""
    return (Rung(name, recipe, checkpoint="last"),
            Rung(f"{name}_guards", recipe, guards=True, reuse=name, checkpoint="last"))


RUNGS: tuple[Rung, ...] = (
    Rung("baseline", {}),
    Rung("noise", NOISE),
    Rung("pushforward", {**NOISE, "pushforward_steps": 1}),
    Rung("kstep", {**NOISE, "pushforward_steps": 1, "rollout_steps": 3, "curriculum_epochs": 6}),
    Rung("guards", {}, guards=True, reuse="kstep"),
    Rung("rotation", ROTATION, guards=True),
    Rung("frame", {**NOISE, "pushforward_steps": 1, "rollout_steps": 3,
                   "curriculum_epochs": 6, "frame": "vessel"}, guards=True),
    Rung("clip", {**NOISE, "pushforward_steps": 1, "rollout_steps": 3,
                  "curriculum_epochs": 6, "frame": "vessel", "grad_clip": 1.0}, guards=True),
    Rung("wall", {**NOISE, "pushforward_steps": 1, "rollout_steps": 3, "curriculum_epochs": 6,
                  "max_rotation": np.pi, "wall_features": 1.5}, guards=True),
    Rung("ensemble", ROTATION, guards=True, reuse="rotation", members=3),
    Rung("history", {**ROTATION, "history": 2}, guards=True),
    Rung("history_lr", {**ROTATION, "history": 2, "lr": 3e-4}, guards=True),
    Rung("history_1step", HISTORY, guards=True),
    Rung("history3", {**HISTORY, "history": 3}, guards=True),
    Rung("history_ensemble", HISTORY, guards=True, reuse="history_1step", members=3),
    Rung("history_walk", WALK, guards=True),
    Rung("walk_ensemble", WALK, guards=True, reuse="history_walk", members=3),
    Rung("history_pf", {**WALK, "pushforward_steps": 1}, guards=True),
    Rung("history_sg", {**ROTATION, "history": 2, "noise_walk": True,
                        "stop_history_gradient": True}, guards=True),
    Rung("walk_shared", {**WALK, "noise_shared": 0.5}, guards=True),
    Rung("shared_ensemble", {**WALK, "noise_shared": 0.5}, guards=True,
         reuse="walk_shared", members=3),
    Rung("walk_noise3", {**WALK, "noise_std": 0.03}, guards=True),
    Rung("noise3_ensemble", {**WALK, "noise_std": 0.03}, guards=True,
         reuse="walk_noise3", members=3),
    # the default recipe with the distance and direction to the nearest vessel node (1.5 r)
    Rung("walk_wall", {**WALK, "wall_features": 1.5}, guards=True),
    # the models alone (guards off): the default recipe, and it with wall noise (clot nodes near
    # the wall moved through it, the targets by half: the model learns to come back; 0.1 r)
    Rung("walk_alone", WALK, reuse="history_walk"),
    Rung("walk_wallnoise", {**WALK, "wall_noise": 0.1}),
    Rung("wallnoise_guards", {**WALK, "wall_noise": 0.1}, guards=True, reuse="walk_wallnoise"),
    # wall noise with signed wall features (the signed distance to the wall and its normal,
    # cut off at 0.5 r: what tells a node that crossed the wall from one inside), alone and
    # with the guards
    Rung("wallnoise_signed", SIGNED),
    Rung("signed_guards", SIGNED, guards=True, reuse="wallnoise_signed"),
    # its seed spread: seeds 0 and 1 alone, and the two as an ensemble (guards off)
    Rung("signed_seeds", SIGNED, reuse="wallnoise_signed", members=2),
    # the control (signed features without the wall noise) and twice the wall noise, alone
    Rung("signed_alone", {**WALK, "wall_features": 0.5, "wall_signed": True}),
    Rung("wallnoise2_signed", {**SIGNED, "wall_noise": 0.2}),
    # the rollout's speed-up: the same with history noise (the clot shifted in the frames
    # before s_{t-1}, the target unchanged: the history's clot-wide acceleration is not
    # carried over), alone, seeds 0 and 1 (and the two as an ensemble), and with the guards;
    # and it with half of the random-walk noise's variance common to the clot (a clot-wide
    # velocity error the target takes back), alone, seeds 0 and 1
    Rung("signed_histnoise", HISTNOISE),
    Rung("histnoise_seeds", HISTNOISE, reuse="signed_histnoise", members=2),
    Rung("histnoise_guards", HISTNOISE, guards=True, reuse="signed_histnoise"),
    Rung("histnoise_shared", {**HISTNOISE, "noise_shared": 0.5}),
    Rung("histshared_seeds", {**HISTNOISE, "noise_shared": 0.5}, reuse="histnoise_shared",
         members=2),
    # the rollout's speed error kept step after step: the same with speed noise (the clot's
    # input motion 1 + N(0, S^2) times the truth, the target unchanged: the model is shown a
    # clot off its speed and the true next frame), S = 0.03 (seeds 0 and 1) and 0.1, alone
    # and with the guards; and the history-noise recipe with time scaling (each window's clot
    # motion played up to 1.5x faster or slower: speeds beyond the data's), alone and guarded
    Rung("speed03", SPEED03),
    Rung("speed03_seeds", SPEED03, reuse="speed03", members=2),
    Rung("speed03_guards", SPEED03, guards=True, reuse="speed03"),
    Rung("speed10", SPEED10),
    Rung("speed10_guards", SPEED10, guards=True, reuse="speed10"),
    Rung("tscale", TSCALE),
    Rung("tscale_guards", TSCALE, guards=True, reuse="tscale"),
    # a rollout's clot drifts off the true track and the step speeds up a clot that comes in
    # off its path: the same with direction noise (the clot's input motion turned, the target
    # unchanged), alone and guarded, and with the speed noise 0.1 as well (seeds 0 and 1), and
    # with three times the direction noise
    Rung("direction10", DIRECTION),
    Rung("direction10_guards", DIRECTION, guards=True, reuse="direction10"),
    Rung("dirspeed", DIRSPEED),
    Rung("dirspeed_guards", DIRSPEED, guards=True, reuse="dirspeed"),
    Rung("dirspeed_seeds", DIRSPEED, reuse="dirspeed", members=2),
    Rung("dirspeed3", DIRSPEED3),
    # which checkpoint: the lowest one-step validation MSE (the rungs above) picked epoch 5 of
    # 25 for dirspeed's seed 1; direction and speed noise without the history noise, picking by
    # the validation rollout, and the last epoch's checkpoint of the same trainings (what
    # --select-by last keeps), alone and guarded, seeds 0-3 (members alone and as an
    # ensemble); the history-noise recipe's last checkpoints
    Rung("nohist_rollout", NOHIST_ROLLOUT),
    Rung("nohist_rollout_guards", NOHIST_ROLLOUT, guards=True, reuse="nohist_rollout"),
    Rung("nohist_last", NOHIST_ROLLOUT, reuse="nohist_rollout", checkpoint="last"),
    Rung("nohist_last_guards", NOHIST_ROLLOUT, guards=True, reuse="nohist_rollout",
         checkpoint="last"),
    Rung("nohist_rollout_seeds", NOHIST_ROLLOUT, reuse="nohist_rollout", members=4),
    Rung("nohist_last_seeds", NOHIST_ROLLOUT, reuse="nohist_rollout", members=4,
         checkpoint="last"),
    Rung("histnoise_last", HISTNOISE, reuse="signed_histnoise", checkpoint="last"),
    Rung("histnoise_last_seeds", HISTNOISE, reuse="signed_histnoise", members=2,
         checkpoint="last"),
    # the last checkpoints of the direction + speed noise recipe with the history noise
    # (dirspeed): seed 0 alone and guarded, seeds 0-4 alone (each, and as an ensemble) and
    # the ensemble guarded; members 3 and 4 trained with --select-by last (the same last
    # checkpoint: the rule does not change the training)
    Rung("dirspeed_last", DIRSPEED, reuse="dirspeed", checkpoint="last"),
    Rung("dirspeed_last_guards", DIRSPEED, guards=True, reuse="dirspeed", checkpoint="last"),
    Rung("dirspeed_last_seeds", DIRSPEED_LAST, reuse="dirspeed", members=5, checkpoint="last"),
    Rung("dirspeed_last_ens_guards", DIRSPEED_LAST, guards=True, reuse="dirspeed", members=5,
         checkpoint="last"),
    # the same recipe trained with --select-by last (for a dataset without the rungs above,
    # e.g. ClotEntry), alone and guarded
    Rung("robust", DIRSPEED_LAST),
    Rung("robust_guards", DIRSPEED_LAST, guards=True, reuse="robust"),
    # its control without the history noise, guarded (ClotEntry: is it the history noise that
    # makes the step ignore the history's acceleration? measured: no, 0.58x CV against 0.61x)
    Rung("robust_nohist_guards", {**DIRSPEED_LAST, "history_noise": 0.0}, guards=True),
    # the default recipe with the velocity split along and across the local vessel axis
    # (--axis-features 2: the wall's normals within about 2 r), guarded and alone
    Rung("walk_axis", AXIS, guards=True),
    Rung("axis_alone", AXIS, reuse="walk_axis"),
    # it with the wall term in the loss, alone and guarded; seeds 0 and 1 alone
    Rung("axis_wall", AXIS_WALL),
    Rung("axis_wall_guards", AXIS_WALL, guards=True, reuse="axis_wall"),
    Rung("axis_wall_seeds", AXIS_WALL, reuse="axis_wall", members=2),
    Rung("axis_wall1", AXIS_WALL1),
    Rung("axis_wall1_seeds", AXIS_WALL1, reuse="axis_wall1", members=2),
    # seeds 0 and 1 of it (each member also scored alone: the seed spread), alone and guarded
    Rung("axis_seeds", AXIS, reuse="walk_axis", members=2),
    Rung("axis_ens_guards", AXIS, guards=True, reuse="walk_axis", members=2),
    # seeds 0-2 of it guarded (member 2 the third seed; each member also scored alone), and the
    # default recipe's seeds 0 and 1 guarded (the control: does the axis split's gain repeat?)
    Rung("axis_ens3_guards", AXIS, guards=True, reuse="walk_axis", members=3),
    Rung("walk_ens2_guards", WALK, guards=True, reuse="history_walk", members=2),
    # the split with wall noise and signed wall features, alone and guarded
    Rung("axis_signed", AXIS_SIGNED),
    Rung("axis_signed_guards", AXIS_SIGNED, guards=True, reuse="axis_signed"),
    # seeds 0 and 1 (0-2) of the split as a committee: every step the members' mean
    # prediction, guarded, is fed back to all (thrombojax.simulator.committee), alone and guarded
    Rung("axis_committee", AXIS, reuse="walk_axis", members=2, committee=True),
    Rung("axis_committee_guards", AXIS, guards=True, reuse="walk_axis", members=2,
         committee=True),
    Rung("axis_committee3_guards", AXIS, guards=True, reuse="walk_axis", members=3,
         committee=True),
    # the split with swell noise (5 %, 10 %), alone and guarded
    Rung("axis_swell", AXIS_SWELL),
    Rung("axis_swell_guards", AXIS_SWELL, guards=True, reuse="axis_swell"),
    Rung("axis_swell10", AXIS_SWELL10),
    Rung("axis_swell10_guards", AXIS_SWELL10, guards=True, reuse="axis_swell10"),
    # the 10 % swell noise's last checkpoint (its lowest one-step validation MSE fell on epoch 6
    # of 25: the noise makes the clean one step worse as it trains), alone and guarded; seeds
    # 0-1 and 0-2 of it (each member also scored alone), alone and guarded
    Rung("axis_swell10_last", AXIS_SWELL10, reuse="axis_swell10", checkpoint="last"),
    Rung("axis_swell10_last_guards", AXIS_SWELL10, guards=True, reuse="axis_swell10",
         checkpoint="last"),
    Rung("axis_swell10_last_seeds", AXIS_SWELL10, reuse="axis_swell10", members=2,
         checkpoint="last"),
    Rung("axis_swell10_last_ens_guards", AXIS_SWELL10, guards=True, reuse="axis_swell10",
         members=2, checkpoint="last"),
    Rung("axis_swell10_last_seeds3", AXIS_SWELL10, reuse="axis_swell10", members=3,
         checkpoint="last"),
    Rung("axis_swell10_last_ens3_guards", AXIS_SWELL10, guards=True, reuse="axis_swell10",
         members=3, checkpoint="last"),
    # seeds 0-4 of it, alone and guarded, and the five as a committee alone
    Rung("axis_swell10_last_seeds5", AXIS_SWELL10, reuse="axis_swell10", members=5,
         checkpoint="last"),
    Rung("axis_swell10_last_ens5_guards", AXIS_SWELL10, guards=True, reuse="axis_swell10",
         members=5, checkpoint="last"),
    Rung("axis_swell10_last_committee5", AXIS_SWELL10, reuse="axis_swell10", members=5,
         checkpoint="last", committee=True),
    # rotation ensembles (thrombojax.simulator.rotations): one model on 4 or 8 rotated copies
    # of each simulation, turned back and averaged; seed 0 alone and guarded, seeds 0-1 each
    Rung("axis_swell10_last_rot4", AXIS_SWELL10, reuse="axis_swell10", checkpoint="last",
         rotations=4),
    Rung("axis_swell10_last_rot4_guards", AXIS_SWELL10, guards=True, reuse="axis_swell10",
         checkpoint="last", rotations=4),
    Rung("axis_swell10_last_rot8", AXIS_SWELL10, reuse="axis_swell10", checkpoint="last",
         rotations=8),
    Rung("axis_swell10_last_seeds_rot4", AXIS_SWELL10, reuse="axis_swell10", members=2,
         checkpoint="last", rotations=4),
    # it with uniformly random orientations in training: seed 0 alone and guarded, seeds 0-1,
    # seed 0 as a rotation ensemble of 4 copies (guarded too), seeds 0-2 alone,
    # seeds 0-1 / 0-2 each on 4 copies
    *last_alone_and_guarded("axis_swell10_haar", AXIS_SWELL10_HAAR),
    Rung("axis_swell10_haar_seeds", AXIS_SWELL10_HAAR, reuse="axis_swell10_haar", members=2,
         checkpoint="last"),
    Rung("axis_swell10_haar_ens_guards", AXIS_SWELL10_HAAR, guards=True,
         reuse="axis_swell10_haar", members=2, checkpoint="last"),
    Rung("axis_swell10_haar_rot4", AXIS_SWELL10_HAAR, reuse="axis_swell10_haar",
         checkpoint="last", rotations=4),
    Rung("axis_swell10_haar_rot4_guards", AXIS_SWELL10_HAAR, guards=True,
         reuse="axis_swell10_haar", checkpoint="last", rotations=4),
    Rung("axis_swell10_haar_seeds_rot4", AXIS_SWELL10_HAAR, reuse="axis_swell10_haar",
         members=2, checkpoint="last", rotations=4),
    Rung("axis_swell10_haar_seeds3", AXIS_SWELL10_HAAR, reuse="axis_swell10_haar", members=3,
         checkpoint="last"),
    Rung("axis_swell10_haar_seeds3_rot4", AXIS_SWELL10_HAAR, reuse="axis_swell10_haar",
         members=3, checkpoint="last", rotations=4),
    # it in the vessel's frame: seed 0 alone and guarded, seeds 0-1 / 0-2 alone and guarded,
    # seeds 0-4 alone (each also scored alone)
    *last_alone_and_guarded("axis_swell10_frame", AXIS_SWELL10_FRAME),
    Rung("axis_swell10_frame_seeds", AXIS_SWELL10_FRAME, reuse="axis_swell10_frame", members=2,
         checkpoint="last"),
    Rung("axis_swell10_frame_ens_guards", AXIS_SWELL10_FRAME, guards=True,
         reuse="axis_swell10_frame", members=2, checkpoint="last"),
    Rung("axis_swell10_frame_seeds3", AXIS_SWELL10_FRAME, reuse="axis_swell10_frame",
         members=3, checkpoint="last"),
    Rung("axis_swell10_frame_seeds3_guards", AXIS_SWELL10_FRAME, guards=True,
         reuse="axis_swell10_frame", members=3, checkpoint="last"),
    Rung("axis_swell10_frame_seeds5", AXIS_SWELL10_FRAME, reuse="axis_swell10_frame",
         members=5, checkpoint="last"),
    # both frames with speed noise 0.1, and with time scaling 1.5 instead (for vessels of many
    # shapes): alone and guarded
    *last_alone_and_guarded("axis_swell10_speed", AXIS_SWELL10_SPEED),
    *last_alone_and_guarded("axis_swell10_frame_speed", AXIS_SWELL10_FRAME_SPEED),
    *last_alone_and_guarded("axis_swell10_tscale", AXIS_SWELL10_TSCALE),
    *last_alone_and_guarded("axis_swell10_frame_tscale", AXIS_SWELL10_FRAME_TSCALE),
    *last_alone_and_guarded("axis_swell10_frame_tscale2", AXIS_SWELL10_FRAME_TSCALE2),
    # it with each addition ``ladder_recipes.AXIS_SWELL10_FRAME_TSCALE_<SUFFIX>``
    *(rung for suffix in ("cm", "room", "outlet", "outlet_hn", "outlet_nohist", "stretch",
                          "stretch30", "stretch_nohist", "stretch_shape", "rest",
                          "rest_stretch")
      for rung in last_alone_and_guarded(
          f"axis_swell10_frame_tscale_{suffix}",
          getattr(ladder_recipes, f"AXIS_SWELL10_FRAME_TSCALE_{suffix.upper()}"))),
    # it with the wall term weighted 3x: seed 0 (the last checkpoint alone and guarded), seeds
    # 0-1 as an ensemble alone and guarded
    *last_alone_and_guarded("axis_swell10_wall3", AXIS_SWELL10_WALL3),
    Rung("axis_swell10_wall3_seeds", AXIS_SWELL10_WALL3, reuse="axis_swell10_wall3",
         members=2, checkpoint="last"),
    Rung("axis_swell10_wall3_ens_guards", AXIS_SWELL10_WALL3, guards=True,
         reuse="axis_swell10_wall3", members=2, checkpoint="last"),
    # the 3 % swell noise, its last checkpoint alone and guarded
    *last_alone_and_guarded("axis_swell03_last", AXIS_SWELL03),
    # the 5 % swell noise's last checkpoint, alone and guarded
    Rung("axis_swell_last", AXIS_SWELL, reuse="axis_swell", checkpoint="last"),
    Rung("axis_swell_last_guards", AXIS_SWELL, guards=True, reuse="axis_swell",
         checkpoint="last"),
    # the 10 % swell noise with wall noise and signed wall features, alone and guarded
    Rung("axis_signed_swell10", AXIS_SIGNED_SWELL10),
    Rung("axis_signed_swell10_guards", AXIS_SIGNED_SWELL10, guards=True,
         reuse="axis_signed_swell10"),
    # its last checkpoint, alone and guarded (on ClotEntry the swell noise's best one-step
    # checkpoint was epoch 1 of 4 and rolled out far worse than the last)
    Rung("axis_signed_swell10_last", AXIS_SIGNED_SWELL10, reuse="axis_signed_swell10",
         checkpoint="last"),
    Rung("axis_signed_swell10_last_guards", AXIS_SIGNED_SWELL10, guards=True,
         reuse="axis_signed_swell10", checkpoint="last"),
    # the 10 % swell noise with the clot-wide error weighted 10x: last checkpoint, both ways
    *last_alone_and_guarded("axis_swell10_cm_last", AXIS_SWELL10_CM),
    # the prior without the history frame, last checkpoint, alone and guarded (the control of
    # the two below)
    *last_alone_and_guarded("follow_nohist_last", FOLLOW_NOHIST),
    # the prior without the history frame and the clot-wide error weighted: last checkpoint,
    # alone and guarded
    *last_alone_and_guarded("follow_nohist_cm_last", FOLLOW_NOHIST_CM),
    # it in the vessel's frame: last checkpoint, alone and guarded
    *last_alone_and_guarded("follow_cm_frame_last", FOLLOW_NOHIST_CM_FRAME),
    # its seeds 0-2 as an ensemble, guarded and alone (each member also scored alone: the
    # seed spread)
    Rung("follow_nohist_cm_last_ens3_guards", FOLLOW_NOHIST_CM, guards=True,
         reuse="follow_nohist_cm_last", members=3, checkpoint="last"),
    Rung("follow_nohist_cm_last_seeds3", FOLLOW_NOHIST_CM, reuse="follow_nohist_cm_last",
         members=3, checkpoint="last"),
    # it with the lateral hold, last checkpoint, alone and guarded; seeds 0-2 as an ensemble,
    # guarded and alone
    *last_alone_and_guarded("follow_hold_last", FOLLOW_HOLD),
    Rung("follow_hold_last_ens3_guards", FOLLOW_HOLD, guards=True, reuse="follow_hold_last",
         members=3, checkpoint="last"),
    Rung("follow_hold_last_seeds3", FOLLOW_HOLD, reuse="follow_hold_last", members=3,
         checkpoint="last"),
    # it with the k-step loss (3 steps after one push-forward step; 6 steps), last checkpoint,
    # alone and guarded; seeds 0-2 as an ensemble, guarded and alone
    # and with speed noise and wall features (``follow_speed*_*``: noise 0.1, 0.3, 0.5), noise
    # 0.3 with the room (at 0.5 and 1.5 r; with the outlet features) or the clot's shape
    # (``follow_room30*``, ``..._shape30``)
    # and, with and without the room, warmed up over 0.7 epochs (``*_w07``: for more sims), and
    # noise 0.3 with the clot's clearance instead of its room (``follow_clear30``)
    *(rung for name, recipe in (("follow_kstep", FOLLOW_KSTEP), ("follow_kstep6", FOLLOW_KSTEP6),
                                ("follow_speed", FOLLOW_SPEED), ("follow_room", FOLLOW_ROOM),
                                ("follow_speed30", FOLLOW_SPEED30),
                                ("follow_speed50", FOLLOW_SPEED50),
                                ("follow_room30", FOLLOW_ROOM30),
                                ("follow_room30_wide", FOLLOW_ROOM30_WIDE),
                                ("follow_room30_outlet", FOLLOW_ROOM30_OUTLET),
                                ("follow_shape30", FOLLOW_SHAPE30),
                                ("follow_speed30_w07", ladder_recipes.FOLLOW_SPEED30_W07),
                                ("follow_room30_w07", ladder_recipes.FOLLOW_ROOM30_W07),
                                ("follow_clear30", ladder_recipes.FOLLOW_CLEAR30))
      for rung in (
          Rung(f"{name}_last", recipe, checkpoint="last"),
          Rung(f"{name}_last_guards", recipe, guards=True, reuse=f"{name}_last",
               checkpoint="last"),
          Rung(f"{name}_last_ens3_guards", recipe, guards=True, reuse=f"{name}_last",
               members=3, checkpoint="last"),
          Rung(f"{name}_last_seeds3", recipe, reuse=f"{name}_last", members=3,
               checkpoint="last"))),
    # the speed-noise recipe's seeds 0-5 as an ensemble, guarded (each member also scored
    # alone, guarded: the spread of six seeds)
    Rung("follow_speed_last_ens6_guards", FOLLOW_SPEED, guards=True, reuse="follow_speed_last",
         members=6, checkpoint="last"),
    # seeds 0-11 of the speed-noise recipe as one ensemble, guarded
    Rung("follow_speed_last_ens12_guards", FOLLOW_SPEED, guards=True,
         reuse="follow_speed_last", members=12, checkpoint="last"),
    # the room recipe's seeds 0-5 as an ensemble, guarded (each member also scored alone,
    # guarded), to set against the speed-noise recipe's six
    Rung("follow_room_last_ens6_guards", FOLLOW_ROOM, guards=True, reuse="follow_room_last",
         members=6, checkpoint="last"),
    # the same six as a committee (every step their mean, guarded, fed back to all), guarded
    # and alone
    Rung("follow_speed_last_committee6_guards", FOLLOW_SPEED, guards=True,
         reuse="follow_speed_last", members=6, checkpoint="last", committee=True),
    Rung("follow_speed_last_committee6", FOLLOW_SPEED, reuse="follow_speed_last", members=6,
         checkpoint="last", committee=True),
    # the split with the vessel-following prior, guarded and alone
    Rung("follow", FOLLOW, guards=True),
    Rung("follow_alone", FOLLOW, reuse="follow"),
    # the prior without the history frame, and with history noise, guarded and alone
    Rung("follow_nohist", FOLLOW_NOHIST, guards=True),
    Rung("follow_nohist_alone", FOLLOW_NOHIST, reuse="follow_nohist"),
    Rung("follow_histnoise", FOLLOW_HISTNOISE, guards=True),
    Rung("follow_histnoise_alone", FOLLOW_HISTNOISE, reuse="follow_histnoise"),
    # the prior without the history frame, trained on the rollout phase only
    Rung("follow_steady", FOLLOW_STEADY, guards=True),
    Rung("follow_steady_alone", FOLLOW_STEADY, reuse="follow_steady"),
)
