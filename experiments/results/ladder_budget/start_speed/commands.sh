#!/bin/bash
# The commands behind this folder (2026-12-07), run from the repository root on the 2-core CPU
# (Intel Xeon), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set, on
# this CPU's bendvessel.h5 (fingerprint 2d7931d0...) and clotentry.h5. The base models (outlet,
# without the start speed) are the outlet recipe's BendVessel seeds 0 and 1 (37 epochs) and
# ClotEntry seeds 13-16 (2 epochs) trained for ../coherence_stretch/; their rows that
# ../guards_exit/ measured are copied here and reused by cross_eval.py. Checkpoints are not
# committed; the new trainings' config.json, metrics.jsonl and loss.png are in training/.
#
# The new models were trained, and the rows start_* first rolled out, with the option's first
# name, --pace-features (config key pace_features; the same code), renamed --start-speed
# (start_speed) before it landed because "pace" already names the guards' per-step factor; the
# runs' config.json keys were renamed to match, the row JSONs renamed pace_* -> start_* (their
# "command" fields keep the first names), and the tables below written again from them.
OUT=experiments/results/ladder_budget/start_speed
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s96   # the base runs
P=/work/exp/s99   # the runs with the start speed

# 1. BendVessel: the outlet recipe (the config of its seeds) plus --start-speed, seeds 0 and 1
# side by side (37 epochs, 38 min each; the time is in training/*/metrics.jsonl).
train_bv() {  # SEED OUT
    thrombojax train --config experiments/results/ladder_budget/bendvessel_room/follow_room30_last/config.json \
        --dataset data/bendvessel.h5 --seed $1 --outlet-features 2 --start-speed --out $2 --quiet
}
train_bv 0 $P/bv_pace_s0 & train_bv 1 $P/bv_pace_s1 & wait

# 2. ClotEntry: the outlet recipe's 2-epoch config plus --start-speed, seeds 13-16, two at a
# time (the first pair beside BendVessel's rollouts of 3).
C=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
for pair in "13 14" "15 16"; do
    for s in $pair; do
        thrombojax train --config $C --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 \
            --seed $s --select-by last --outlet-features 2 --start-speed \
            --out $P/ce_pace_s$s --quiet &
    done
    wait
done

# 3. BendVessel rollouts: held out (005, 012, 019) and validation (009), each seed and the
# ensemble of the two (e2), guarded at auto (the rigid copy's fitted tolerance), with the step
# after containment reading the velocity from before it (wallvel), with containment only
# (contain), and alone; the same rows of the outlet seeds without the start speed.
AUTO=0.20727364718914032
for d in heldout validation; do
    mkdir -p $OUT/bendvessel_$d
    for m in s0 s1 e2; do for k in auto alone wallvel contain; do
        cp experiments/results/ladder_budget/guards_exit/$d/outlet_${m}_$k.json $OUT/bendvessel_$d/
    done; done
done
source experiments/results/ladder_budget/pair_rows.sh  # rows, pair_tables
ROWS="$(rows outlet $R/bv_outlet_s0 $R/bv_outlet_s1) $(rows start $P/bv_pace_s0 $P/bv_pace_s1)"
T="BendVessel: the outlet recipe's seeds 0 and 1 (37 epochs) and their ensemble (e2), without (outlet) and with the clot's start speed as an input (start, --start-speed); guarded at auto (0.207 r), with the step after containment reading the velocity from before it (wallvel), with containment only (contain), and alone"
pair_tables $OUT "$T" "outlet start" $ROWS

# 4. How much each BendVessel step reads the start speed, teacher-forced (held out, before the
# exit).
python $OUT/start_gain.py $OUT/bendvessel_gain.md data/bendvessel.h5 \
    bendvessel_005,bendvessel_012,bendvessel_019 start_s0=$P/bv_pace_s0 start_s1=$P/bv_pace_s1 \
    outlet_s0=$R/bv_outlet_s0 outlet_s1=$R/bv_outlet_s1

# 5. ClotEntry rollouts (2,048 nodes), guarded at auto: held out (008, 009) seeds 13 and 14 with
# the start speed (seeds 15 and 16 alone were not rolled out: the first two ended 5-6 r off),
# the four as one ensemble (e4), and validation (007) the ensemble; the outlet rows of
# ../guards_exit/ copied as they are.
CAUTO=0.3759520649909973
G=experiments/results/ladder_budget/guards_exit
mkdir -p $OUT/clotentry_heldout $OUT/clotentry_validation
cp $G/clotentry_heldout/ce_s13_auto.json $OUT/clotentry_heldout/outlet_s13_auto.json
cp $G/clotentry_heldout/ce_s15_auto.json $OUT/clotentry_heldout/outlet_s15_auto.json
cp $G/clotentry_heldout/ce_e4_auto.json $OUT/clotentry_heldout/outlet_e4_auto.json
cp $G/clotentry_validation/ce_e4_auto.json $OUT/clotentry_validation/outlet_e4_auto.json
E4S=$P/ce_pace_s13+$P/ce_pace_s14+$P/ce_pace_s15+$P/ce_pace_s16
E4O=$R/ce_out_s13+$R/ce_out_s14+$R/ce_out_s15+$R/ce_out_s16
A="outlet_s13_auto=$R/ce_out_s13:guards,tolerance_r=$CAUTO outlet_s15_auto=$R/ce_out_s15:guards,tolerance_r=$CAUTO start_s13_auto=$P/ce_pace_s13:guards,tolerance_r=$CAUTO start_s14_auto=$P/ce_pace_s14:guards,tolerance_r=$CAUTO"
V="outlet_e4_auto=$E4O:guards,tolerance_r=$CAUTO start_e4_auto=$E4S:guards,tolerance_r=$CAUTO"
T="ClotEntry (2,048 nodes): the outlet recipe's 2-epoch seeds 13-16 and their four-member ensemble (e4), without (outlet) and with the clot's start speed as an input (start, --start-speed); guarded at auto (0.376 r)"
python $CE --nodes 2048 $OUT/clotentry_heldout data/clotentry.h5 clotentry_008,clotentry_009 "$T, held out" $A $V &
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/clotentry_validation data/clotentry.h5 clotentry_007 "$T, validation" $V &
wait

# 6. Two more BendVessel seeds (2 and 3) with --start-speed, side by side (36 min each), then
# their rows and the four seeds 0-3 as one ensemble (e4), against the outlet seeds 2 and 3 of
# ../guards_exit/ (run by ../guards_exit/commands.sh from /work/exp/s97; rows copied). The tables
# above were then written again with every row (the same rows and labels, reused).
train_bv 2 $P/bv_start_s2 & train_bv 3 $P/bv_start_s3 & wait
Q=/work/exp/s97
G=experiments/results/ladder_budget/guards_exit
for d in heldout validation; do
    for m in s2 s3; do for k in auto alone; do cp $G/$d/outlet_${m}_$k.json $OUT/bendvessel_$d/; done; done
    for k in auto alone contain; do cp $G/$d/outlet_e4_$k.json $OUT/bendvessel_$d/; done
done
E4O=$R/bv_outlet_s0+$R/bv_outlet_s1+$Q/bv_outlet_s2+$Q/bv_outlet_s3
E4S=$P/bv_pace_s0+$P/bv_pace_s1+$P/bv_start_s2+$P/bv_start_s3
O="outlet_s2_auto=$Q/bv_outlet_s2:guards,tolerance_r=$AUTO outlet_s2_alone=$Q/bv_outlet_s2 outlet_s3_auto=$Q/bv_outlet_s3:guards,tolerance_r=$AUTO outlet_s3_alone=$Q/bv_outlet_s3 outlet_e4_auto=$E4O:guards,tolerance_r=$AUTO outlet_e4_contain=$E4O:guards,coherence=0 outlet_e4_alone=$E4O"
H=""
for s in 2 3; do H="$H start_s${s}_auto=$P/bv_start_s$s:guards,tolerance_r=$AUTO start_s${s}_contain=$P/bv_start_s$s:guards,coherence=0 start_s${s}_alone=$P/bv_start_s$s"; done
E="start_e4_auto=$E4S:guards,tolerance_r=$AUTO start_e4_contain=$E4S:guards,coherence=0 start_e4_alone=$E4S"
T="BendVessel: the outlet recipe's seeds 0-3 (37 epochs), the ensembles of seeds 0-1 (e2) and 0-3 (e4), without (outlet) and with the clot's start speed as an input (start, --start-speed); guarded at auto (0.207 r), with the step after containment reading the velocity from before it (wallvel), with containment only (contain), and alone"
python $CE $OUT/bendvessel_heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 "$T, held out" $ROWS $O $E $H &
python $CE --sims-kind "validation simulation" $OUT/bendvessel_validation data/bendvessel.h5 bendvessel_009 "$T, validation" $ROWS $O $E &
wait
L=""; for p in outlet start; do for m in s0 s1 e2; do for k in auto contain alone; do L="$L,${p}_${m}_$k"; done; done; done
L="$L,outlet_s2_auto,outlet_s2_alone,outlet_s3_auto,outlet_s3_alone,outlet_e4_auto,outlet_e4_contain,outlet_e4_alone"
L="$L,start_s2_auto,start_s2_contain,start_s2_alone,start_s3_auto,start_s3_contain,start_s3_alone,start_e4_auto,start_e4_contain,start_e4_alone"
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --force --out $OUT/track.md \
    $OUT/bendvessel_heldout ${L#,}
