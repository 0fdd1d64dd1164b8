"""The stability ladder's training recipes: the option sets its rungs train with
(``experiments/ladder_rungs.py`` names the rungs; ``experiments/ladder.py`` runs them)."""

from __future__ import annotations

import numpy as np

__all__ = ["COMMON", "STUDY_SIZE", "SMALL_MGN", "SIGNED", "HISTNOISE", "WALK", "AXIS",
           "AXIS_WALL", "AXIS_WALL1", "AXIS_SIGNED", "FOLLOW", "FOLLOW_NOHIST",
           "FOLLOW_HISTNOISE", "FOLLOW_STEADY", "AXIS_SWELL", "AXIS_SWELL10", "AXIS_SWELL03",
           "AXIS_SWELL10_WALL3", "AXIS_SWELL10_HAAR", "AXIS_SWELL10_FRAME", "AXIS_SWELL10_SPEED",
           "AXIS_SWELL10_FRAME_SPEED", "AXIS_SWELL10_TSCALE", "AXIS_SWELL10_FRAME_TSCALE",
           "AXIS_SWELL10_FRAME_TSCALE2", "AXIS_SWELL10_FRAME_TSCALE_CM",
           "AXIS_SWELL10_FRAME_TSCALE_ROOM", "AXIS_SWELL10_FRAME_TSCALE_OUTLET",
           "AXIS_SWELL10_FRAME_TSCALE_OUTLET_HN", "AXIS_SWELL10_FRAME_TSCALE_OUTLET_NOHIST",
           "AXIS_SWELL10_FRAME_TSCALE_STRETCH", "AXIS_SWELL10_FRAME_TSCALE_STRETCH30",
           "AXIS_SWELL10_FRAME_TSCALE_STRETCH_NOHIST", "AXIS_SWELL10_FRAME_TSCALE_STRETCH_SHAPE",
           "AXIS_SWELL10_FRAME_TSCALE_REST", "AXIS_SWELL10_FRAME_TSCALE_REST_STRETCH",
           "AXIS_SIGNED_SWELL10",
           "AXIS_SWELL10_CM", "FOLLOW_NOHIST_CM", "FOLLOW_NOHIST_CM_FRAME", "FOLLOW_HOLD",
           "FOLLOW_KSTEP", "FOLLOW_KSTEP6", "FOLLOW_SPEED", "NOISE", "ROTATION", "HISTORY",
           "DIRECTION", "DIRSPEED", "DIRSPEED3", "DIRSPEED_LAST", "FOLLOW_ROOM", "FOLLOW_SPEED30",
           "FOLLOW_SPEED50", "FOLLOW_ROOM30", "FOLLOW_ROOM30_WIDE", "FOLLOW_ROOM30_OUTLET",
           "FOLLOW_SHAPE30",
           "FOLLOW_SPEED30_W07", "FOLLOW_ROOM30_W07", "FOLLOW_CLEAR30",
           "NOHIST_ROLLOUT",
           "SPEED03", "SPEED10", "TSCALE"]

SMALL_MGN = {"hidden": 32, "processor_size": 5, "max_neighbors": 12}
_SCHEDULE = {"max_rotation": 0.0, "warmup_epochs": 2.0}
COMMON = {**_SCHEDULE, "batch_size": 4, "model_config": SMALL_MGN}
# ``--size study``: the study's MeshGraphNet (hidden 128, 15 blocks, 32 neighbours) and batch 8,
# for an accelerator (each rung otherwise as above)
STUDY_SIZE = {**_SCHEDULE, "batch_size": 8}
NOISE = {"noise_std": 0.01}  # vessel radii
# the rotation rung's recipe (the `rollout` recipe of `thrombojax train`), shared by the
# ensemble rung's members
ROTATION = {**NOISE, "pushforward_steps": 1, "rollout_steps": 3, "curriculum_epochs": 6,
            "max_rotation": np.pi}
# a step that also reads the acceleration before t, trained with the single-step loss (with
# ``noise_walk``: the `history` recipe, the default of `thrombojax train`)
HISTORY = {**NOISE, "max_rotation": np.pi, "history": 2}
WALK = {**HISTORY, "noise_walk": True}  # the `history` recipe (rung `history_walk`)
# it with wall noise 0.1 r and signed wall features cut off at 0.5 r (rung `wallnoise_signed`)
SIGNED = {**WALK, "wall_noise": 0.1, "wall_features": 0.5, "wall_signed": True}
# it with history noise 0.02 r (the clot-wide history acceleration not carried over)
HISTNOISE = {**SIGNED, "history_noise": 0.02}
# it with speed noise (the clot's input motion scaled by 1 + N(0, S^2), the target unchanged)
SPEED03, SPEED10 = {**HISTNOISE, "speed_noise": 0.03}, {**HISTNOISE, "speed_noise": 0.1}
# it with time scaling (each window played up to 1.5x faster or slower)
TSCALE = {**HISTNOISE, "time_scale": 1.5}
# it with direction noise (the clot's input motion turned by a rotation of N(0, 0.1^2) rad per
# axis, the target unchanged), and that with the speed noise 0.1 as well (0.1 and 0.3 rad)
DIRECTION, DIRSPEED = ({**HISTNOISE, "direction_noise": 0.1},
                       {**SPEED10, "direction_noise": 0.1})
DIRSPEED3 = {**SPEED10, "direction_noise": 0.3}
# direction and speed noise 0.1 without the history noise (the signed recipe with both), its
# best checkpoint picked by a rollout on the validation simulation each epoch
NOHIST_ROLLOUT = {**SIGNED, "speed_noise": 0.1, "direction_noise": 0.1, "select_by": "rollout"}
# direction and speed noise with the history noise (``DIRSPEED``), keeping the last epoch's
# checkpoint (``--select-by last``): ``thrombojax train --recipe robust``
DIRSPEED_LAST = {**DIRSPEED, "select_by": "last"}
AXIS = {**WALK, "axis_features": 2.0}  # the default recipe + vessel-axis velocity split
# it with the wall term in the loss (predictions further through the wall than the truth
# charged 10x, thrombojax.train.wall_loss): rungs ``axis_wall*``
AXIS_WALL = {**AXIS, "wall_loss_weight": 10.0}
AXIS_WALL1 = {**AXIS, "wall_loss_weight": 1.0}  # and weighted 1x: rungs ``axis_wall1*``
# it with the wall noise and signed wall features of SIGNED: told along the vessel where to go,
# and across it where the wall is and that a node crossed it (rungs ``axis_signed``)
AXIS_SIGNED = {**SIGNED, "axis_features": 2.0}
# it with the vessel-following prior: the step moves the clot along the vessel at its speed
# and the model learns the rest (rungs ``follow``, ``follow_alone``)
FOLLOW = {**AXIS, "follow_axis": 2.0}
# it with swell noise of 5 % and 10 % (the clot scaled about its centroid in the inputs, the
# target taking half back): rolled out alone, the recipe's clot swells and leaves the vessel
AXIS_SWELL, AXIS_SWELL10 = {**AXIS, "swell_noise": 0.05}, {**AXIS, "swell_noise": 0.1}
# it with the rotation's angle from the uniform measure on the rotations (every orientation
# equally likely; the default angle favours the dataset's own): rungs ``axis_swell10_haar*``
AXIS_SWELL10_HAAR = {**AXIS_SWELL10, "uniform_rotation": True}
# it in the rigid vessel's own frame (``--frame vessel``: invariant to the orientation up to
# rounding, so a turned simulation enters as the dataset's own): rungs ``axis_swell10_frame*``
AXIS_SWELL10_FRAME = {**AXIS_SWELL10, "frame": "vessel"}
# both with speed noise 0.1 (the clot's input motion scaled, the target unchanged): trained on
# vessels of many shapes, the frame's rollouts ran ahead on BendVessel-sized vessels and lagged
# on a longer one, one bias along the vessel: rungs ``axis_swell10_speed*``,
# ``axis_swell10_frame_speed*``
AXIS_SWELL10_SPEED = {**AXIS_SWELL10, "speed_noise": 0.1}
AXIS_SWELL10_FRAME_SPEED = {**AXIS_SWELL10_FRAME, "speed_noise": 0.1}
# both with time scaling 1.5 instead (each window's clot motion played up to 1.5x faster or
# slower, the target with it): speed noise shows a clot off its speed and the true next frame,
# so it teaches a speed to return to; time scaling shows every speed as a true one, so the
# step must carry the speed its input has: rungs ``axis_swell10_tscale*``,
# ``axis_swell10_frame_tscale*``
AXIS_SWELL10_TSCALE = {**AXIS_SWELL10, "time_scale": 1.5}
AXIS_SWELL10_FRAME_TSCALE = {**AXIS_SWELL10_FRAME, "time_scale": 1.5}
AXIS_SWELL10_FRAME_TSCALE2 = {**AXIS_SWELL10_FRAME, "time_scale": 2.0}  # and up to 2x
# the vessel frame with time scaling, and the clot-wide error weighted 10x: its rollouts gained
# or lost speed in the steady slide, where the true clot-wide acceleration is 0 (rungs
# ``axis_swell10_frame_tscale_cm*``); and with the clot-wide mean wall distance as an input (wall
# features cut off at 0.5 r: the room the clot has, which grows in the outlet's flare where the
# true clot speeds up; rungs ``axis_swell10_frame_tscale_room*``)
AXIS_SWELL10_FRAME_TSCALE_CM = {**AXIS_SWELL10_FRAME_TSCALE, "clot_mean_weight": 10.0}
AXIS_SWELL10_FRAME_TSCALE_ROOM = {**AXIS_SWELL10_FRAME_TSCALE, "wall_features": 0.5,
                                  "wall_clot_mean": True}
# and with the outlet features (2 r): teacher-forced, these steps gave the exit's speed-up only
# through the history's acceleration (none from the geometry), so rollouts lagged in the last
# frames; the features show where the vessel's open end lies ahead of the clot's motion (rungs
# ``axis_swell10_frame_tscale_outlet*``)
AXIS_SWELL10_FRAME_TSCALE_OUTLET = {**AXIS_SWELL10_FRAME_TSCALE, "outlet_features": 2.0}
# teacher-forced, that step still gave the exit only through the history: so the history's
# clot-wide acceleration noised (0.02 r per frame^2, rungs ``..._outlet_hn*``), or no history
# (the step reads s_{t-1} alone, rungs ``..._outlet_nohist*``)
AXIS_SWELL10_FRAME_TSCALE_OUTLET_HN = {**AXIS_SWELL10_FRAME_TSCALE_OUTLET, "history_noise": 0.02}
AXIS_SWELL10_FRAME_TSCALE_OUTLET_NOHIST = {**AXIS_SWELL10_FRAME_TSCALE_OUTLET, "history": 1}
# with stretch noise 0.1 instead (the clot stretched along its motion in the inputs, the target
# taking half back): rolled out, these models' clot fronts ran up to 6 r ahead of the true
# front while the rears stayed, and the centroid followed (rungs ``..._stretch*``)
AXIS_SWELL10_FRAME_TSCALE_STRETCH = {**AXIS_SWELL10_FRAME_TSCALE, "stretch_noise": 0.1}
# and with stretch noise 0.3: with 0.1 the step took back a fifth of a stretch rate and none
# of a stretch (rungs ``..._stretch30*``)
AXIS_SWELL10_FRAME_TSCALE_STRETCH30 = {**AXIS_SWELL10_FRAME_TSCALE, "stretch_noise": 0.3}
# and the stretch noise on the outlet features without the history (the exit read from the
# vessel, the clot's length kept): rungs ``..._stretch_nohist*``
AXIS_SWELL10_FRAME_TSCALE_STRETCH_NOHIST = {**AXIS_SWELL10_FRAME_TSCALE_OUTLET_NOHIST,
                                            "stretch_noise": 0.1}
# the stretch noise 0.1 with the clot's shape as an input (each node's place along the motion,
# the clot's length and width, over 1 r): with the noise alone the step kept a static stretch,
# which a message-passing step cannot see from its neighbours (rungs ``..._stretch_shape*``)
AXIS_SWELL10_FRAME_TSCALE_STRETCH_SHAPE = {**AXIS_SWELL10_FRAME_TSCALE_STRETCH,
                                           "shape_features": 1.0}
# the clot's rest state read by the step: MeshGraphNet's clot-clot edges get their displacement
# in the simulation's first frame beside the current one (DeepMind's deforming plate), so each
# edge's strain is an input; the swell noise's swollen clots are then strained ones (rungs
# ``..._rest*``)
AXIS_SWELL10_FRAME_TSCALE_REST = {**AXIS_SWELL10_FRAME_TSCALE, "rest_edges": True}
# and the stretch noise 0.1 with it: the stretched inputs are then strained edges the step sees
# (rungs ``..._rest_stretch*``)
AXIS_SWELL10_FRAME_TSCALE_REST_STRETCH = {**AXIS_SWELL10_FRAME_TSCALE_STRETCH, "rest_edges": True}
# the 10 % swell noise with the wall term weighted 3x: rungs ``axis_swell10_wall3*``
AXIS_SWELL10_WALL3 = {**AXIS_SWELL10, "wall_loss_weight": 3.0}
# 3 %: on ClotEntry's 5 r clot it moves the ends by about what 5 % does on BendVessel's 3 r clot
# (0.075 r); 10 % spoilt ClotEntry's one step
AXIS_SWELL03 = {**AXIS, "swell_noise": 0.03}
# the 10 % swell noise with the wall noise and signed wall features of AXIS_SIGNED: the swelling
# taken back clot-wide, a node that crossed the wall taken back where it crossed
AXIS_SIGNED_SWELL10 = {**AXIS_SIGNED, "swell_noise": 0.1}
# the clot-wide error weighted 10 times more in the loss: teacher-forced on ClotEntry, the 10 %
# model's clot-mean acceleration along its motion was off by about ten times the truth's
# (which is near 0), even on its training simulations; a rollout integrates exactly that error
AXIS_SWELL10_CM = {**AXIS_SWELL10, "clot_mean_weight": 10.0}
# it without the history frame (the model cannot carry its last acceleration over: with the
# history, ``history_gain`` 0.94-1.07 and the clot sped up along the vessel), and it with the
# history kept but its clot-wide acceleration noised (history noise 0.02 r)
FOLLOW_NOHIST = {**FOLLOW, "history": 1}
FOLLOW_HISTNOISE = {**FOLLOW, "history_noise": 0.02}
# the prior without the history frame, trained only on the frames rollouts run on (windows
# from the dataset's ``skip_frames`` on: the start from rest, which the model cannot tell
# from the steady slide without the history, left out)
FOLLOW_STEADY = {**FOLLOW_NOHIST, "skip_frames": "dataset"}
# the prior without the history frame, the clot-wide error weighted 10x: the prior turns the
# clot's motion onto the vessel (with the weight alone, ClotEntry's rollout drifted sideways
# into the wall and stalled), the weighted loss fits the clot's speed changes along it
FOLLOW_NOHIST_CM = {**FOLLOW_NOHIST, "clot_mean_weight": 10.0}
# it in the rigid vessel's own frame (each ClotEntry vessel its own): rungs ``follow_cm_frame*``
FOLLOW_NOHIST_CM_FRAME = {**FOLLOW_NOHIST_CM, "frame": "vessel"}
# it with the lateral hold: the clot-wide mean of the model's acceleration across the vessel's
# axis (2 r) taken out of every step (rollouts drifted sideways first; rungs ``follow_hold_*``)
FOLLOW_HOLD = {**FOLLOW_NOHIST_CM, "lateral_hold": 2.0}
# it with the k-step unrolled loss instead (the clot's drift, which a rollout integrates, is what
# the loss sees: each step's target brings the rollout back onto the true frame): one
# push-forward step, then 3 steps with gradients through them, k grown over 3 epochs (rungs
# ``follow_kstep_*``); and 6 steps with gradients, no push-forward (rungs ``follow_kstep6_*``)
FOLLOW_KSTEP = {**FOLLOW_NOHIST_CM, "pushforward_steps": 1, "rollout_steps": 3,
                "curriculum_epochs": 3.0}
FOLLOW_KSTEP6 = {**FOLLOW_NOHIST_CM, "rollout_steps": 6, "curriculum_epochs": 3.0}
# it with speed noise 0.1 and wall features cut off at 0.5 r: the true clot returns within a
# few frames to the speed its room in the vessel allows (experiments/results/clot_speed/), so
# the step is shown a clot off its speed and where the wall is (rungs ``follow_speed_*``)
FOLLOW_SPEED = {**FOLLOW_NOHIST_CM, "speed_noise": 0.1, "wall_features": 0.5}
# it with the clot-wide mean of the wall distance as an input too: its rollouts move at an almost
# constant speed (0.28-0.31 r per frame where the truth's runs 0.20-0.38 with the vessel's width),
# and the clot's mean clipped wall distance follows the true speed (+0.4 to +0.7 per simulation)
# where a message-passing step sees only its neighbours' distances (rungs ``follow_room_*``)
FOLLOW_ROOM = {**FOLLOW_SPEED, "wall_clot_mean": True}
# it with speed noise 0.3 and 0.5 instead of 0.1: every ClotEntry model so far keeps a speed
# error it is given (``speed_carry`` 0.99-1.01 without speed noise, 0.75 with 0.1) where the
# solver's damping brings the clot to its terminal speed within a frame; a step that cannot
# tell the true speed from the noised one pulls back the share the noise outweighs what the
# vessel tells it, so a larger noise asks for a larger pull-back (rungs ``follow_speed30_*``,
# ``follow_speed50_*``)
FOLLOW_SPEED30 = {**FOLLOW_SPEED, "speed_noise": 0.3}
FOLLOW_SPEED50 = {**FOLLOW_SPEED, "speed_noise": 0.5}
# the room recipe with speed noise 0.3: given the clot's room (``wall_clot_mean``) its rollout's
# speed followed the truth's (correlation +0.6 to +0.8) but kept every speed error it made; with
# noise 0.3 the step pulls a speed error back to what it reads from the vessel, and the room is
# what tells it where the true clot slows (rungs ``follow_room30_*``)
FOLLOW_ROOM30 = {**FOLLOW_SPEED30, "wall_clot_mean": True}
# it with the wall features cut off at 1.5 r instead of 0.5 r: the clot's clearance in the
# vessel is 0.7-1.2 r, so at 0.5 r most clot nodes see no wall and the room saturates
# (rungs ``follow_room30_wide_*``)
FOLLOW_ROOM30_WIDE = {**FOLLOW_ROOM30, "wall_features": 1.5}
# it with the outlet features (``outlet_features`` 2 r: where the clot stands against the
# vessel's open end): BendVessel's true clot speeds up as it leaves the vessel and the room step
# did not; with them it does (experiments/results/ladder_budget/bendvessel_speed_noise/,
# .../clotentry_outlet/; rungs ``follow_room30_outlet_*``)
FOLLOW_ROOM30_OUTLET = {**FOLLOW_ROOM30, "outlet_features": 2.0}
# speed noise 0.3 with the clot's shape as an input (``shape_features`` 1 r: each clot node's
# place along the motion and the clot's length and width): within every ClotEntry simulation the
# true clot's speed follows its length along the motion (correlation -0.73 to -0.98 of 10-frame
# means) more closely than the clearance at its centroid (+0.68 to +0.92;
# experiments/results/ladder_budget/clotentry_speed_room/clot_length.md; rungs
# ``follow_shape30_*``)
FOLLOW_SHAPE30 = {**FOLLOW_SPEED30, "shape_features": 1.0}
# speed noise 0.3, and the room recipe with it, with a warm-up of 0.7 epochs instead of 2: for
# 2 epochs on a dataset of 20 training simulations (``generate clotentry --sims 23``), the same
# optimiser steps and warm-up share as 6 epochs on the preset's 7 (rungs ``follow_speed30_w07_*``,
# ``follow_room30_w07_*``; experiments/results/ladder_budget/clotentry_more_sims/)
FOLLOW_SPEED30_W07 = {**FOLLOW_SPEED30, "warmup_epochs": 0.7}
FOLLOW_ROOM30_W07 = {**FOLLOW_ROOM30, "warmup_epochs": 0.7}
# speed noise 0.3 with the clot's clearance instead of its room (``clearance_features`` 1 r: the
# distance from the clot's centroid to the nearest vessel node): the room is read through the
# clot's own nodes, so where the containment guard puts a node back the room changes and the
# guarded clot's speed with it (experiments/results/ladder_budget/clotentry_speed_room/margin/);
# the clearance reads the clot through its centroid alone (rungs ``follow_clear30_*``;
# experiments/results/ladder_budget/clotentry_clearance/)
FOLLOW_CLEAR30 = {**FOLLOW_SPEED30, "clearance_features": 1.0}
