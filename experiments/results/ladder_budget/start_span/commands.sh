#!/bin/bash
# The commands behind this folder (2026-12-08), run from the repository root on the 2-core CPU
# (Intel Xeon), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set, on
# this CPU's files (bendvessel.h5 fingerprint 2d7931d0...). The runs were written to /work/exp/s101
# (checkpoints not committed; config.json, metrics.jsonl and loss.png of each are in training/).
# The rows without the start speed (outlet_*) and with it over one frame (start_*) are
# ../start_speed/'s JSONs, copied here and reused by cross_eval.py; their models are
# ../start_speed/'s (R, P below).
OUT=experiments/results/ladder_budget/start_span
SS=experiments/results/ladder_budget/start_speed
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s96   # the outlet recipe's runs (../guards_exit/, ../coherence_stretch/)
P=/work/exp/s99   # the runs with the start speed (../start_speed/)
S=/work/exp/s101  # the runs with the start speed over the span from rest (this folder)

# 0. The datasets' facts (no model): per simulation the clot's mean speed from rest to the rollout's start,
# its speed into it, its pace after it and how much faster it ends than it slid.
python $OUT/facts.py $OUT/bendvessel_facts.md data/bendvessel.h5
python $OUT/facts.py $OUT/clotentry_facts.md data/clotentry.h5

# 1. Training: the outlet recipe with --start-speed --start-span T0 (5 on BendVessel, 40 on
# ClotEntry), the seeds of ../start_speed/. BendVessel 0 and 1 side by side, then ClotEntry 13
# and 14, then 15 and 16.
C=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
ROOM=experiments/results/ladder_budget/bendvessel_room/follow_room30_last/config.json
train_bv() {  # SEED
    thrombojax train --config $ROOM --dataset data/bendvessel.h5 --seed $1 --outlet-features 2 \
        --start-speed --start-span 5 --out $S/bv_span_s$1 --quiet
}
train_ce() {  # SEED
    thrombojax train --config $C --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 \
        --seed $1 --select-by last --outlet-features 2 --start-speed --start-span 40 \
        --out $S/ce_span_s$1 --quiet
}
train_bv 0 & train_bv 1 & wait
train_ce 13 & train_ce 14 & wait
train_ce 15 & train_ce 16 & wait

# 2. BendVessel, held out (005, 012, 019) and validation (009): seeds 0 and 1 and their
# ensemble, guarded at auto (0.207 r), wallvel, containment only and alone; the track split;
# then, teacher-forced, the exit's speed-up each step predicts per simulation (exit_read.py).
AUTO=0.20727364718914032
source experiments/results/ladder_budget/pair_rows.sh  # copy_rows, rows, pair_tables
copy_rows $SS $OUT "outlet start"
ROWS="$(rows outlet $R/bv_outlet_s0 $R/bv_outlet_s1) $(rows start $P/bv_pace_s0 $P/bv_pace_s1) $(rows span $S/bv_span_s0 $S/bv_span_s1)"
T="BendVessel: the outlet recipe's seeds 0 and 1 (37 epochs) and their ensemble (e2), without the start speed (outlet), with the speed into the rollout's start frame (start, --start-speed) and with the mean speed from rest to it (span, --start-speed --start-span 5); guarded at auto (0.207 r), with the step after containment reading the velocity from before it (wallvel), with containment only (contain), and alone"
pair_tables $OUT "$T" "outlet start span" $ROWS
MODELS="outlet_s0=$R/bv_outlet_s0 outlet_s1=$R/bv_outlet_s1 start_s0=$P/bv_pace_s0 start_s1=$P/bv_pace_s1 span_s0=$S/bv_span_s0 span_s1=$S/bv_span_s1"
python $OUT/exit_read.py $OUT/bendvessel_exit_heldout.md data/bendvessel.h5 \
    bendvessel_005,bendvessel_012,bendvessel_019,bendvessel_009 $MODELS
python $OUT/exit_read.py $OUT/bendvessel_exit_all.md data/bendvessel.h5 \
    $(python -c "print(','.join(f'bendvessel_{i:03d}' for i in range(20)))") $MODELS

# 3. ClotEntry, 2,048 nodes, guarded at auto (0.376 r): held out (008, 009) seeds 13 and 14 and
# the three four-seed ensembles (13-16); validation (007) the ensembles.
CAUTO=0.3759520649909973
SN=experiments/results/ladder_budget/start_speed_noise
mkdir -p $OUT/clotentry_heldout $OUT/clotentry_validation
for f in outlet_s13_auto outlet_e4_auto start_s13_auto start_s14_auto start_e4_auto; do
    cp $SN/clotentry_heldout/$f.json $OUT/clotentry_heldout/; done
for f in outlet_e4_auto start_e4_auto; do cp $SN/clotentry_validation/$f.json $OUT/clotentry_validation/; done
E4O=$R/ce_out_s13+$R/ce_out_s14+$R/ce_out_s15+$R/ce_out_s16
E4S=$P/ce_pace_s13+$P/ce_pace_s14+$P/ce_pace_s15+$P/ce_pace_s16
E4N=$S/ce_span_s13+$S/ce_span_s14+$S/ce_span_s15+$S/ce_span_s16
A="outlet_s13_auto=$R/ce_out_s13:guards,tolerance_r=$CAUTO start_s13_auto=$P/ce_pace_s13:guards,tolerance_r=$CAUTO start_s14_auto=$P/ce_pace_s14:guards,tolerance_r=$CAUTO span_s13_auto=$S/ce_span_s13:guards,tolerance_r=$CAUTO span_s14_auto=$S/ce_span_s14:guards,tolerance_r=$CAUTO"
V="outlet_e4_auto=$E4O:guards,tolerance_r=$CAUTO start_e4_auto=$E4S:guards,tolerance_r=$CAUTO span_e4_auto=$E4N:guards,tolerance_r=$CAUTO"
T="ClotEntry (2,048 nodes): the outlet recipe's 2-epoch seeds 13-16 and their four-member ensemble (e4), without the start speed (outlet), with the speed into the rollout's start frame (start, --start-speed) and with the mean speed from rest to it (span, --start-speed --start-span 40); guarded at auto (0.376 r)"
python $CE --nodes 2048 $OUT/clotentry_heldout data/clotentry.h5 clotentry_008,clotentry_009 "$T, held out" $A $V &
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/clotentry_validation data/clotentry.h5 clotentry_007 "$T, validation" $V &
wait

# 4. ClotEntry, a second draw: seeds 17-20 trained the same way (two at a time, beside a
# fresh-clone test suite), their four-member ensemble held out and on validation.
train_ce 17 & train_ce 18 & wait
train_ce 19 & train_ce 20 & wait
E=$S/ce_span_s17+$S/ce_span_s18+$S/ce_span_s19+$S/ce_span_s20
T="ClotEntry (2,048 nodes): the outlet recipe with --start-speed --start-span 40, a second draw of four 2-epoch seeds (17-20) as one ensemble (span2_e4); guarded at auto (0.376 r)"
mkdir -p $OUT/clotentry_heldout_draw2 $OUT/clotentry_validation_draw2
python $CE --nodes 2048 $OUT/clotentry_heldout_draw2 data/clotentry.h5 clotentry_008,clotentry_009 "$T, held out" span2_e4_auto=$E:guards,tolerance_r=$CAUTO &
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/clotentry_validation_draw2 data/clotentry.h5 clotentry_007 "$T, validation" span2_e4_auto=$E:guards,tolerance_r=$CAUTO &
wait

# 5. The run files committed in training/.
for r in bv_span_s0 bv_span_s1 ce_span_s13 ce_span_s14 ce_span_s15 ce_span_s16 ce_span_s17 \
         ce_span_s18 ce_span_s19 ce_span_s20; do
    mkdir -p $OUT/training/$r
    cp $S/$r/config.json $S/$r/metrics.jsonl $S/$r/loss.png $OUT/training/$r/
done
