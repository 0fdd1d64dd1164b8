#!/bin/bash
# The commands behind this folder (2026-12-07), run from the repository root on the 2-core CPU
# (Intel Xeon), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set, on
# this CPU's files (bendvessel.h5 fingerprint 2d7931d0...). The runs were written to /work/exp/s100
# (checkpoints not committed; config.json, metrics.jsonl and loss.png of each are in training/).
# The rows without the start speed (outlet_*) and with it unnoised (start_*) are
# ../start_speed/'s JSONs, copied here and reused by cross_eval.py; their models are
# ../start_speed/'s (R, P below). The first two ClotEntry rows with the noise were measured into
# /work/exp/s100/ce_heldout under the labels ssn_s13_auto / ssn_s14_auto (the commands their
# JSONs record) and copied here as noise_s13_auto / noise_s14_auto.
OUT=experiments/results/ladder_budget/start_speed_noise
SS=experiments/results/ladder_budget/start_speed
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s96   # the outlet recipe's runs (../guards_exit/, ../coherence_stretch/)
P=/work/exp/s99   # the runs with the start speed (../start_speed/)
S=/work/exp/s100  # the runs with the start speed noised in training (this folder)

# 1. Training: the outlet recipe, --start-speed and --start-speed-noise 0.3, the seeds of
# ../start_speed/. ClotEntry 13 and 14 first (side by side, 11.3-11.4 min each), then BendVessel
# 0 and 1 (side by side, 45.3-45.6 min each, with the rollouts of step 2 beside them), then
# ClotEntry 15 and 16 (15.3 min each, with BendVessel's rollouts of step 3 beside them).
C=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
ROOM=experiments/results/ladder_budget/bendvessel_room/follow_room30_last/config.json
train_ce() {  # SEED
    thrombojax train --config $C --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 \
        --seed $1 --select-by last --outlet-features 2 --start-speed --start-speed-noise 0.3 \
        --out $S/ce_ssn_s$1 --quiet
}
train_bv() {  # SEED
    thrombojax train --config $ROOM --dataset data/bendvessel.h5 --seed $1 --outlet-features 2 \
        --start-speed --start-speed-noise 0.3 --out $S/bv_ssn_s$1 --quiet
}
train_ce 13 & train_ce 14 & wait
train_bv 0 & train_bv 1 & wait
train_ce 15 & train_ce 16 & wait

# 2. ClotEntry, seeds 13 and 14 alone, guarded at auto (0.376 r), beside BendVessel's training;
# then how much the steps read the start speed, teacher-forced (../start_speed/start_gain.py).
CAUTO=0.3759520649909973
mkdir -p $S/ce_heldout
python $CE --nodes 2048 $S/ce_heldout data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry held out: start speed with noise 0.3" \
    ssn_s13_auto=$S/ce_ssn_s13:guards,tolerance_r=$CAUTO ssn_s14_auto=$S/ce_ssn_s14:guards,tolerance_r=$CAUTO
python $SS/start_gain.py $S/clotentry_gain.md data/clotentry.h5 clotentry_008,clotentry_009 \
    start_s13=$P/ce_pace_s13 ssn_s13=$S/ce_ssn_s13 outlet_s13=$R/ce_out_s13
cp $S/clotentry_gain.md $OUT/clotentry_gain.md   # ssn_s13: the noised step (noise_s13 below)

# 3. BendVessel, held out (005, 012, 019) and validation (009): seeds 0 and 1 and their
# ensemble, guarded at auto (0.207 r), wallvel, containment only and alone; the track split;
# the teacher-forced gain.
AUTO=0.20727364718914032
source experiments/results/ladder_budget/pair_rows.sh  # copy_rows, rows, pair_tables
copy_rows $SS $OUT "outlet start"
ROWS="$(rows outlet $R/bv_outlet_s0 $R/bv_outlet_s1) $(rows start $P/bv_pace_s0 $P/bv_pace_s1) $(rows noise $S/bv_ssn_s0 $S/bv_ssn_s1)"
T="BendVessel: the outlet recipe's seeds 0 and 1 (37 epochs) and their ensemble (e2), without the start speed (outlet), with it (start, --start-speed) and with it noised in training (noise, --start-speed --start-speed-noise 0.3); guarded at auto (0.207 r), with the step after containment reading the velocity from before it (wallvel), with containment only (contain), and alone"
pair_tables $OUT "$T" "outlet start noise" $ROWS
python $SS/start_gain.py $OUT/bendvessel_gain.md data/bendvessel.h5 \
    bendvessel_005,bendvessel_012,bendvessel_019 start_s0=$P/bv_pace_s0 start_s1=$P/bv_pace_s1 \
    noise_s0=$S/bv_ssn_s0 noise_s1=$S/bv_ssn_s1

# 4. ClotEntry, 2,048 nodes: held out (008, 009) every single model measured so far and the
# three four-seed ensembles (13-16); validation (007) the ensembles. Guarded at auto.
mkdir -p $OUT/clotentry_heldout $OUT/clotentry_validation
for f in outlet_s13_auto outlet_s15_auto outlet_e4_auto start_s13_auto start_s14_auto start_e4_auto; do
    cp $SS/clotentry_heldout/$f.json $OUT/clotentry_heldout/; done
for f in outlet_e4_auto start_e4_auto; do cp $SS/clotentry_validation/$f.json $OUT/clotentry_validation/; done
for s in 13 14; do cp $S/ce_heldout/ssn_s${s}_auto.json $OUT/clotentry_heldout/noise_s${s}_auto.json; done
E4O=$R/ce_out_s13+$R/ce_out_s14+$R/ce_out_s15+$R/ce_out_s16
E4S=$P/ce_pace_s13+$P/ce_pace_s14+$P/ce_pace_s15+$P/ce_pace_s16
E4N=$S/ce_ssn_s13+$S/ce_ssn_s14+$S/ce_ssn_s15+$S/ce_ssn_s16
A="outlet_s13_auto=$R/ce_out_s13:guards,tolerance_r=$CAUTO outlet_s15_auto=$R/ce_out_s15:guards,tolerance_r=$CAUTO start_s13_auto=$P/ce_pace_s13:guards,tolerance_r=$CAUTO start_s14_auto=$P/ce_pace_s14:guards,tolerance_r=$CAUTO noise_s13_auto=$S/ce_ssn_s13:guards,tolerance_r=$CAUTO noise_s14_auto=$S/ce_ssn_s14:guards,tolerance_r=$CAUTO"
V="outlet_e4_auto=$E4O:guards,tolerance_r=$CAUTO start_e4_auto=$E4S:guards,tolerance_r=$CAUTO noise_e4_auto=$E4N:guards,tolerance_r=$CAUTO"
T="ClotEntry (2,048 nodes): the outlet recipe's 2-epoch seeds 13-16 and their four-member ensemble (e4), without the start speed (outlet), with it (start, --start-speed) and with it noised in training (noise, --start-speed --start-speed-noise 0.3); guarded at auto (0.376 r)"
python $CE --nodes 2048 $OUT/clotentry_heldout data/clotentry.h5 clotentry_008,clotentry_009 "$T, held out" $A $V &
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/clotentry_validation data/clotentry.h5 clotentry_007 "$T, validation" $V &
wait

# 5. ClotEntry, the start speed at the pace (an oracle: the simulation's true mean speed over
# the rollout), seed 13 with the start speed unnoised and noised (beside the tests of a fresh clone).
python $OUT/start_at_pace.py $OUT/clotentry_at_pace.md data/clotentry.h5 clotentry_008,clotentry_009 \
    $CAUTO start_s13=$P/ce_pace_s13 noise_s13=$S/ce_ssn_s13

# 6. The run files committed in training/.
for r in bv_ssn_s0 bv_ssn_s1 ce_ssn_s13 ce_ssn_s14 ce_ssn_s15 ce_ssn_s16; do
    mkdir -p $OUT/training/$r
    cp $S/$r/config.json $S/$r/metrics.jsonl $S/$r/loss.png $OUT/training/$r/
done
