#!/bin/bash
# The commands behind this folder (2026-12-08), run from the repository root on the 2-core CPU
# (Intel Xeon), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set, on
# this CPU's files (bendvessel.h5 fingerprint 2d7931d0...). The runs were written to /work/exp/s102
# (checkpoints not committed; config.json, metrics.jsonl and loss.png of each are in training/).
# The rows of the outlet recipe as it is (outlet_*) and with the span alone (span_*) are
# ../start_span/'s JSONs, copied here and reused by cross_eval.py; their models are
# ../start_span/'s (R, S below).
OUT=experiments/results/ladder_budget/span_speedup
SP=experiments/results/ladder_budget/start_span
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s96   # the outlet recipe's runs (../guards_exit/, ../coherence_stretch/)
S=/work/exp/s101  # the runs with the start speed over the span from rest (../start_span/)
W=/work/exp/s102  # the runs with the span and the accelerating windows weighted (this folder)

# 0. No model: where a rollout ends that runs every simulation at the training simulations'
# mean pace along its own true path (one_pace.py), held out and validation, then each training
# simulation against the mean of the others.
BV_TRAIN=$(python -c "print(','.join(f'bendvessel_{i:03d}' for i in range(19) if i not in (5, 9, 12)))")
python $OUT/one_pace.py $OUT/bendvessel_one_pace.md data/bendvessel.h5 $BV_TRAIN \
    bendvessel_005,bendvessel_012,bendvessel_019,bendvessel_009
python $OUT/one_pace.py $OUT/clotentry_one_pace.md data/clotentry.h5 \
    $(python -c "print(','.join(f'clotentry_{i:03d}' for i in range(7)))") clotentry_008,clotentry_009,clotentry_007

# 1. Training: the outlet recipe with --start-speed --start-span T0 (5 on BendVessel, 40 on
# ClotEntry) and --speedup-weight 3, the seeds of ../start_span/. BendVessel 0 and 1 side by
# side, then ClotEntry 13 and 14 (15 and 16 were started and stopped for time, to train the
# next pair instead). Then the BendVessel pair again on 60 simulations (the preset's 20, the
# same arrays, and 40 more; 56 training simulations), for the same optimiser steps.
C=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
ROOM=experiments/results/ladder_budget/bendvessel_room/follow_room30_last/config.json
train_bv() {  # SEED
    thrombojax train --config $ROOM --dataset data/bendvessel.h5 --seed $1 --outlet-features 2 \
        --start-speed --start-span 5 --speedup-weight 3 --out $W/bv_spw_s$1 --quiet
}
train_ce() {  # SEED
    thrombojax train --config $C --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 \
        --seed $1 --select-by last --outlet-features 2 --start-speed --start-span 40 \
        --speedup-weight 3 --out $W/ce_spw_s$1 --quiet
}
train_bv 0 & train_bv 1 & wait
train_ce 13 & train_ce 14 & wait
thrombojax generate bendvessel --sims 60 --out data/bendvessel60.h5
train_bv60() {  # SEED: 11 epochs of 546 steps (6,006; 37 x 156 = 5,772 above), warm-up the same share
    thrombojax train --config $ROOM --dataset data/bendvessel60.h5 --epochs 11 --warmup-epochs 0.57 \
        --seed $1 --outlet-features 2 --start-speed --start-span 5 --speedup-weight 3 \
        --out $W/bv60_spw_s$1 --quiet
}
train_bv60 0  # (seed 1 was started beside it and stopped for time)

# 2. BendVessel, held out (005, 012, 019) and validation (009): seeds 0 and 1 and their
# ensemble, guarded at auto (0.207 r), wallvel, containment only and alone; the track split;
# spw60 seed 0 the same; then, teacher-forced over the 20 simulations, the exit's speed-up each
# step predicts.
AUTO=0.20727364718914032
source experiments/results/ladder_budget/pair_rows.sh  # copy_rows, rows, pair_tables
copy_rows $SP $OUT "outlet span"
# (Run first as pair_tables $OUT "$T" "outlet span spw" with the rows without spw60, as the
# runs came; the second pass below reused every row JSON by its label.)
R60="spw60_s0_auto=$W/bv60_spw_s0:guards,tolerance_r=$AUTO spw60_s0_wallvel=$W/bv60_spw_s0:guards,tolerance_r=$AUTO,keep_velocity_wall=1 spw60_s0_contain=$W/bv60_spw_s0:guards,coherence=0 spw60_s0_alone=$W/bv60_spw_s0"
ROWS="$(rows outlet $R/bv_outlet_s0 $R/bv_outlet_s1) $(rows span $S/bv_span_s0 $S/bv_span_s1) $(rows spw $W/bv_spw_s0 $W/bv_spw_s1) $R60"
T="BendVessel: the outlet recipe's seeds 0 and 1 and their ensemble (e2), as it is (outlet), with the mean speed from rest to the rollout's start (span, --start-speed --start-span 5), with it and the accelerating windows weighted 4x in the loss (spw, --start-speed --start-span 5 --speedup-weight 3), each 37 epochs on the 16 training simulations, and spw seed 0 on 56 training simulations for the same optimiser steps (spw60, 11 epochs); guarded at auto (0.207 r), with the step after containment reading the velocity from before it (wallvel), with containment only (contain), and alone"
python $CE $OUT/bendvessel_heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 "$T, held out" $ROWS
python $CE --sims-kind "validation simulation" $OUT/bendvessel_validation data/bendvessel.h5 bendvessel_009 "$T, validation" $ROWS
labels=""; for p in outlet span spw; do for m in s0 s1 e2; do for k in auto contain alone; do labels="$labels,${p}_${m}_$k"; done; done; done
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --out $OUT/track.md --force \
    $OUT/bendvessel_heldout ${labels#,},spw60_s0_auto,spw60_s0_contain,spw60_s0_alone
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --out $OUT/track_validation.md \
    $OUT/bendvessel_validation outlet_e2_auto,outlet_e2_contain,outlet_e2_alone,span_e2_auto,span_e2_contain,span_e2_alone,spw_s0_auto,spw_s1_auto,spw_e2_auto,spw_e2_contain,spw_e2_alone,spw60_s0_auto,spw60_s0_contain,spw60_s0_alone
python $SP/exit_read.py $OUT/bendvessel_exit_all.md data/bendvessel.h5 \
    $(python -c "print(','.join(f'bendvessel_{i:03d}' for i in range(20)))") \
    outlet_s0=$R/bv_outlet_s0 outlet_s1=$R/bv_outlet_s1 span_s0=$S/bv_span_s0 span_s1=$S/bv_span_s1 \
    spw_s0=$W/bv_spw_s0 spw_s1=$W/bv_spw_s1
python $SP/exit_read.py $OUT/bendvessel_exit_spw60.md data/bendvessel.h5 \
    $(python -c "print(','.join(f'bendvessel_{i:03d}' for i in range(20)))") \
    spw60_s0=$W/bv60_spw_s0

# 3. ClotEntry, 2,048 nodes, guarded at auto (0.376 r): held out (008, 009), seeds 13 and 14.
# (Their ensembles and the validation vessel were started and stopped for time.)
CAUTO=0.3759520649909973
mkdir -p $OUT/clotentry_heldout
for f in outlet_s13_auto span_s13_auto span_s14_auto; do cp $SP/clotentry_heldout/$f.json $OUT/clotentry_heldout/; done
A="outlet_s13_auto=$R/ce_out_s13:guards,tolerance_r=$CAUTO span_s13_auto=$S/ce_span_s13:guards,tolerance_r=$CAUTO span_s14_auto=$S/ce_span_s14:guards,tolerance_r=$CAUTO spw_s13_auto=$W/ce_spw_s13:guards,tolerance_r=$CAUTO spw_s14_auto=$W/ce_spw_s14:guards,tolerance_r=$CAUTO"
T="ClotEntry (2,048 nodes): the outlet recipe's 2-epoch seed 13 as it is (outlet), and seeds 13 and 14 with the mean speed from rest to the rollout's start (span, --start-speed --start-span 40) and with it and the accelerating windows weighted 4x in the loss (spw, --start-speed --start-span 40 --speedup-weight 3); guarded at auto (0.376 r)"
python $CE --nodes 2048 $OUT/clotentry_heldout data/clotentry.h5 clotentry_008,clotentry_009 "$T, held out" $A
