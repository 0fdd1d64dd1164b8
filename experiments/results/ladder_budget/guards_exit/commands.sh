#!/bin/bash
# The commands behind this folder (2026-12-07), run from the repository root on the 2-core CPU
# (Intel Xeon), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set.
# No model was trained: the rows roll out the outlet recipe's seeds trained for
# ../coherence_stretch/ (BendVessel seeds 0 and 1, 37 epochs; ClotEntry 2-epoch seeds 13-16) on
# the same files (this CPU's bendvessel.h5, fingerprint 2d7931d0...). The rows auto, alone and
# stretch (and ClotEntry's ce_*_auto) are ../coherence_stretch/'s JSONs, copied here and reused
# by cross_eval.py. The rows were measured into a folder named coherence_outlet/, renamed
# guards_exit/ before it was committed: the commands the new rows' JSONs record name the old one.
OUT=experiments/results/ladder_budget/guards_exit
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s96   # the runs of ../coherence_stretch/ (checkpoints not committed; their
                  # config.json and metrics.jsonl are in ../coherence_stretch/training/)
AUTO=0.20727364718914032; S12=0.1293611079454422   # ../coherence_stretch/stretch_truth.md
for d in heldout validation; do
    mkdir -p $OUT/$d
    for m in s0 s1 e2; do for k in auto alone; do
        cp experiments/results/ladder_budget/coherence_stretch/$d/outlet_${m}_$k.json $OUT/$d/
    done; done
    cp experiments/results/ladder_budget/coherence_stretch/$d/outlet_e2_stretch.json $OUT/$d/
done

# 1. BendVessel, held out (005, 012, 019) and validation (009), two processes side by side.
# Rows per model (seeds 0, 1 and their ensemble): auto (the default guards, the rigid copy at
# 0.207 r); free (coherence fits and moves only the clot nodes not past the vessel's open end,
# build_guards(free_past_end=True)); soft50 / soft25 (coherence at stiffness 0.5 / 0.25); contain
# (containment only); cohere (coherence only); wallvel (the step after containment reads the
# velocity from before it, keep_velocity_wall, thrombojax rollout --keep-wall-velocity); allvel
# (wallvel and keep_velocity: the velocity from before both guards); alone. The ensemble also
# with the copy stretching up to 1.2x at its auto (stretch) and that with free (freestretch).
ROWS=""
for m in e2 s0 s1; do
    case $m in e2) RUN=$R/bv_outlet_s0+$R/bv_outlet_s1 ;; *) RUN=$R/bv_outlet_$m ;; esac
    ROWS="$ROWS outlet_${m}_auto=$RUN:guards,tolerance_r=$AUTO outlet_${m}_free=$RUN:guards,tolerance_r=$AUTO,free_past_end=1"
    ROWS="$ROWS outlet_${m}_soft50=$RUN:guards,tolerance_r=$AUTO,stiffness=0.5 outlet_${m}_soft25=$RUN:guards,tolerance_r=$AUTO,stiffness=0.25"
    ROWS="$ROWS outlet_${m}_contain=$RUN:guards,coherence=0 outlet_${m}_cohere=$RUN:guards,tolerance_r=$AUTO,containment=0"
    ROWS="$ROWS outlet_${m}_wallvel=$RUN:guards,tolerance_r=$AUTO,keep_velocity_wall=1 outlet_${m}_allvel=$RUN:guards,tolerance_r=$AUTO,keep_velocity=1,keep_velocity_wall=1"
done
for m in s0 s1; do ROWS="$ROWS outlet_${m}_alone=$R/bv_outlet_$m"; done
E=$R/bv_outlet_s0+$R/bv_outlet_s1
ROWS="$ROWS outlet_e2_alone=$E outlet_e2_stretch=$E:guards,tolerance_r=$S12,max_stretch=1.2 outlet_e2_freestretch=$E:guards,tolerance_r=$S12,max_stretch=1.2,free_past_end=1"
TITLE="BendVessel, held out: the outlet recipe's seeds 0 and 1 and their ensemble, guarded at auto (0.207 r) as by default, with coherence freeing the clot nodes past the outlet (free), with coherence at stiffness 0.5 and 0.25 (soft50, soft25: that share of the pull beyond the tolerance per step), with containment only (contain), with coherence only (cohere), with the next step reading the velocity from before containment (wallvel, keep_velocity_wall) and from before both guards (allvel, with keep_velocity); the ensemble also with the copy stretching up to 1.2x at its auto (stretch, 0.129 r) and that with free; alone"
python $CE $OUT/heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 "$TITLE" $ROWS &
python $CE --sims-kind "validation simulation" $OUT/validation data/bendvessel.h5 bendvessel_009 \
    "BendVessel, validation: the same rows" $ROWS &
wait
L=""
for k in auto free soft50 soft25 contain cohere wallvel allvel; do
    L="$L,outlet_s0_$k,outlet_s1_$k,outlet_e2_$k"
done
L="${L#,},outlet_e2_stretch,outlet_e2_freestretch,outlet_s0_alone,outlet_s1_alone,outlet_e2_alone"
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --out $OUT/track.md \
    $OUT/heldout $L $OUT/validation $L

# 1b. Two more seeds of the outlet recipe (2 and 3, 37 epochs, side by side, 2,436-2,438 s each;
# config.json, metrics.jsonl and loss.png in training/), rolled out as seeds 0 and 1 above, alone,
# at auto and with the velocity kept through containment, and the four seeds 0-3 as one ensemble
# (e4). Measured by cross_eval.py into folders of their own (/work/exp/s97/more_heldout,
# more_validation: the commands their JSONs record), the JSONs copied into heldout/ and
# validation/; the commands below, with every row there, wrote the tables.
Q=/work/exp/s97
ROOM=experiments/results/ladder_budget/bendvessel_room/follow_room30_last/config.json
for s in 2 3; do
    thrombojax train --config $ROOM --dataset data/bendvessel.h5 --seed $s --outlet-features 2 \
        --out $Q/bv_outlet_s$s &
done; wait
E4=$R/bv_outlet_s0+$R/bv_outlet_s1+$Q/bv_outlet_s2+$Q/bv_outlet_s3
both_tables() {  # HELD-OUT TITLE: the held-out and validation tables with every row so far
    python $CE $OUT/heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 \
        "$1" $ROWS $ROWS4 &
    python $CE --sims-kind "validation simulation" $OUT/validation data/bendvessel.h5 bendvessel_009 \
        "BendVessel, validation: the same rows" $ROWS $ROWS4 &
    wait
}
ROWS4=""
for m in s2 s3 e4; do
    case $m in e4) RUN=$E4 ;; *) RUN=$Q/bv_outlet_$m ;; esac
    ROWS4="$ROWS4 outlet_${m}_auto=$RUN:guards,tolerance_r=$AUTO outlet_${m}_wallvel=$RUN:guards,tolerance_r=$AUTO,keep_velocity_wall=1 outlet_${m}_alone=$RUN"
done
both_tables "$TITLE; seeds 2 and 3 and the four seeds 0-3 as one ensemble (e4) at auto, wallvel and alone"
# 1c. The four-seed ensemble with the vessel-following prior's centring pull set at rollout time
# (strength 0.5, tolerance 0, as ../bendvessel_pull/inference/; thrombojax rollout --centre-pull
# 0.5 --centre-tolerance 0), alone and guarded at auto. Measured into /work/exp/s97/pull_heldout
# and pull_validation (the commands their JSONs record), copied here; the commands below wrote
# the tables with every row.
ROWS4="$ROWS4 outlet_e4_pull_alone=$E4:alone,centre_pull=0.5,centre_tolerance_r=0 outlet_e4_pull_auto=$E4:guards,tolerance_r=$AUTO,centre_pull=0.5,centre_tolerance_r=0"
both_tables "$TITLE; seeds 2 and 3 and the four seeds 0-3 as one ensemble (e4) at auto, wallvel and alone, and e4 with the centring pull 0.5 set at rollout time (pull), alone and at auto"
L4=outlet_s2_auto,outlet_s3_auto,outlet_e4_auto,outlet_s2_wallvel,outlet_s3_wallvel,outlet_e4_wallvel,outlet_s2_alone,outlet_s3_alone,outlet_e4_alone,outlet_e4_pull_alone,outlet_e4_pull_auto
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --force --out $OUT/track.md \
    $OUT/heldout $L,$L4 $OUT/validation $L,$L4
# 1d. (the next session, same machine and files) The four-seed ensemble with containment only
# (coherence off), with and without the velocity kept through containment, and each with the
# centring pull 0.5 set at rollout time. Measured into /work/exp/s98/e4_heldout and
# e4_validation (the commands their JSONs record), copied here; the commands below, with every
# row there, wrote the tables.
ROWS4="$ROWS4 outlet_e4_contain=$E4:guards,coherence=0 outlet_e4_containvel=$E4:guards,coherence=0,keep_velocity_wall=1"
ROWS4="$ROWS4 outlet_e4_pull_contain=$E4:guards,coherence=0,centre_pull=0.5,centre_tolerance_r=0 outlet_e4_pull_containvel=$E4:guards,coherence=0,keep_velocity_wall=1,centre_pull=0.5,centre_tolerance_r=0"
both_tables "$TITLE; seeds 2 and 3 and the four seeds 0-3 as one ensemble (e4) at auto, wallvel and alone, and e4 with the centring pull 0.5 set at rollout time (pull), alone and at auto; e4 with containment only (contain), that with the velocity kept through containment (containvel), and both with the pull"
L4=$L4,outlet_e4_contain,outlet_e4_containvel,outlet_e4_pull_contain,outlet_e4_pull_containvel
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --force --out $OUT/track.md \
    $OUT/heldout $L,$L4 $OUT/validation $L,$L4
# 1e. (the next session) Two more seeds of the outlet recipe (4 and 5, 37 epochs, side by side,
# 53.7-54.1 minutes each, slowed by ClotEntry rollouts and tests run beside them at times; their
# config.json, metrics.jsonl and loss.png in training/), rolled out at auto, wallvel and alone,
# and the six seeds 0-5 as one ensemble (e6) at auto, wallvel, alone, alone with the pull, and
# with containment only (contain, containvel). Measured into /work/exp/s98/e6_heldout and
# e6_validation (the commands their JSONs record), copied here; the commands below, with every
# row there, wrote the tables.
S=/work/exp/s98
for s in 4 5; do
    thrombojax train --config $ROOM --dataset data/bendvessel.h5 --seed $s --outlet-features 2 \
        --out $S/bv_outlet_s$s &
done; wait
E6=$E4+$S/bv_outlet_s4+$S/bv_outlet_s5
for s in 4 5; do
    ROWS4="$ROWS4 outlet_s${s}_auto=$S/bv_outlet_s$s:guards,tolerance_r=$AUTO outlet_s${s}_wallvel=$S/bv_outlet_s$s:guards,tolerance_r=$AUTO,keep_velocity_wall=1 outlet_s${s}_alone=$S/bv_outlet_s$s"
done
ROWS4="$ROWS4 outlet_e6_auto=$E6:guards,tolerance_r=$AUTO outlet_e6_wallvel=$E6:guards,tolerance_r=$AUTO,keep_velocity_wall=1 outlet_e6_alone=$E6"
ROWS4="$ROWS4 outlet_e6_pull_alone=$E6:alone,centre_pull=0.5,centre_tolerance_r=0 outlet_e6_contain=$E6:guards,coherence=0 outlet_e6_containvel=$E6:guards,coherence=0,keep_velocity_wall=1"
both_tables "$TITLE; seeds 2-5 and the ensembles of seeds 0-3 (e4) and 0-5 (e6) at auto, wallvel and alone, with the centring pull 0.5 set at rollout time (pull), and with containment only (contain), that with the velocity kept through containment (containvel)"
L4=$L4,outlet_s4_auto,outlet_s5_auto,outlet_e6_auto,outlet_s4_wallvel,outlet_s5_wallvel,outlet_e6_wallvel
L4=$L4,outlet_s4_alone,outlet_s5_alone,outlet_e6_alone,outlet_e6_pull_alone,outlet_e6_contain,outlet_e6_containvel
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --force --out $OUT/track.md \
    $OUT/heldout $L,$L4 $OUT/validation $L,$L4

# 2. When the true clot passes the open end (no model)
python $OUT/past_end.py data/bendvessel.h5 --held-out bendvessel_005,bendvessel_012,bendvessel_019 \
    --validation bendvessel_009 --out $OUT/past_end.md

# 3. ClotEntry at 2,048 nodes, coherence at the rigid copy's auto (0.376 r): held out (008, 009)
# the four seeds 13-16 as one ensemble and seeds 13 and 15 with the velocity kept through
# containment (the default rows, ce_*_auto, are ../coherence_stretch/clotentry_heldout/'s);
# validation (007) the ensemble with both. Each process wrote into a folder of its own, two side
# by side, and the JSONs were copied here; these commands, with every row there, wrote the tables.
CAUTO=0.3759520649909973
E4=$R/ce_out_s13+$R/ce_out_s14+$R/ce_out_s15+$R/ce_out_s16
mkdir -p $OUT/clotentry_heldout
cp experiments/results/ladder_budget/coherence_stretch/clotentry_heldout/ce_{s13,s15,e4}_auto.json $OUT/clotentry_heldout/
python $CE --nodes 2048 $OUT/clotentry_heldout data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry, held out: the outlet recipe's 2-epoch seeds 13 and 15 and the four seeds 13-16 as one ensemble, guarded at auto (0.376 r) as by default and with the next step reading the velocity from before containment (wallvel, keep_velocity_wall)" \
    ce_s13_auto=$R/ce_out_s13:guards,tolerance_r=$CAUTO ce_s13_wallvel=$R/ce_out_s13:guards,tolerance_r=$CAUTO,keep_velocity_wall=1 \
    ce_s15_auto=$R/ce_out_s15:guards,tolerance_r=$CAUTO ce_s15_wallvel=$R/ce_out_s15:guards,tolerance_r=$CAUTO,keep_velocity_wall=1 \
    ce_e4_auto=$E4:guards,tolerance_r=$CAUTO ce_e4_wallvel=$E4:guards,tolerance_r=$CAUTO,keep_velocity_wall=1
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/clotentry_validation data/clotentry.h5 clotentry_007 \
    "ClotEntry, validation: the four seeds 13-16 as one ensemble, guarded at auto (0.376 r) and with the velocity kept through containment (wallvel)" \
    ce_e4_auto=$E4:guards,tolerance_r=$CAUTO ce_e4_wallvel=$E4:guards,tolerance_r=$CAUTO,keep_velocity_wall=1

# 3b. (the next session, same machine and files) The ClotEntry ensemble with containment only
# (coherence off), held out and validation. Measured into /work/exp/s98/ce_heldout and
# ce_validation (the commands their JSONs record), copied here; the commands below, with every
# row there, wrote the tables.
python $CE --nodes 2048 $OUT/clotentry_heldout data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry, held out: the outlet recipe's 2-epoch seeds 13 and 15 and the four seeds 13-16 as one ensemble, guarded at auto (0.376 r) as by default and with the next step reading the velocity from before containment (wallvel, keep_velocity_wall); the ensemble with containment only (contain)" \
    ce_s13_auto=$R/ce_out_s13:guards,tolerance_r=$CAUTO ce_s13_wallvel=$R/ce_out_s13:guards,tolerance_r=$CAUTO,keep_velocity_wall=1 \
    ce_s15_auto=$R/ce_out_s15:guards,tolerance_r=$CAUTO ce_s15_wallvel=$R/ce_out_s15:guards,tolerance_r=$CAUTO,keep_velocity_wall=1 \
    ce_e4_auto=$E4:guards,tolerance_r=$CAUTO ce_e4_wallvel=$E4:guards,tolerance_r=$CAUTO,keep_velocity_wall=1 \
    ce_e4_contain=$E4:guards,coherence=0
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/clotentry_validation data/clotentry.h5 clotentry_007 \
    "ClotEntry, validation: the four seeds 13-16 as one ensemble, guarded at auto (0.376 r), with the velocity kept through containment (wallvel) and with containment only (contain)" \
    ce_e4_auto=$E4:guards,tolerance_r=$CAUTO ce_e4_wallvel=$E4:guards,tolerance_r=$CAUTO,keep_velocity_wall=1 \
    ce_e4_contain=$E4:guards,coherence=0
