#!/bin/bash
# The commands behind this folder (2026-12-07), run from the repository root on the 2-core CPU
# (Intel Xeon), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set, on
# this CPU's bendvessel.h5 (fingerprint 2d7931d0...). The base models are the outlet recipe's
# seeds 0 and 1 trained for ../coherence_stretch/ (37 epochs; checkpoints not committed, their
# config.json and metrics.jsonl are in ../coherence_stretch/training/); their rows outlet_s*_* are
# ../guards_exit/'s JSONs, copied here and reused by cross_eval.py. The fine-tunings' config.json,
# metrics.jsonl and loss.png are in training/.
OUT=experiments/results/ladder_budget/guarded_training
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s96   # the base runs
F=/work/exp/s98   # the fine-tuned runs
AUTO=0.20727364718914032   # the rigid copy's auto tolerance (../coherence_stretch/)
for d in heldout validation; do
    mkdir -p $OUT/$d
    cp experiments/results/ladder_budget/guards_exit/$d/outlet_s{0,1}_{auto,alone}.json $OUT/$d/
done

# 1. Fine-tuning from each base's last checkpoint, 8 epochs at lr 3e-4 (0.5 warm-up epochs, then
# the cosine), everything else the base's config; two trainings side by side, 8.5-12.2 minutes
# each (the time of each is in training/*/metrics.jsonl).
#  a. one push-forward step, its prediction guarded (guards) or not (plain); seed 0; without the
#     recipe's speed noise (a first pair with it, 0.3, was stopped after two and three epochs at
#     one-step validation MSE 3-6x the base's; not kept);
#  b. the input frames guarded (inputs) or not (none); seeds 0 and 1; the recipe's noise as is.
fine_tune() {  # SEED NAME EXTRA...
    local s=$1 name=$2; shift 2
    thrombojax train --config $R/bv_outlet_s$s/config.json --dataset data/bendvessel.h5 \
        --seed $s --init-from $R/bv_outlet_s$s --init-checkpoint last --epochs 8 --lr 3e-4 \
        --warmup-epochs 0.5 --select-by last --out $F/ft_${name}_s$s --quiet "$@"
}
fine_tune 0 guards --pushforward-steps 1 --speed-noise 0 --pushforward-guards --guard-coherence 0.2 &
fine_tune 0 plain --pushforward-steps 1 --speed-noise 0 &
wait
for s in 0 1; do
    fine_tune $s inputs --input-guards --guard-coherence 0.2 &
    fine_tune $s none &
    wait
done

# 2. Rollouts on the held-out (005, 012, 019) and validation (009) simulations, guarded at auto
# and alone, each model and the ensembles of seeds 0 and 1 (e2). The rows were measured as the
# trainings finished, into /work/exp/s98/{heldout,validation}_{s0,in0,in1} (the commands their
# JSONs record), and copied here; the commands below, with every row there, wrote the tables.
ROWS=""
for s in 0 1; do
    ROWS="$ROWS outlet_s${s}_auto=$R/bv_outlet_s$s:guards,tolerance_r=$AUTO outlet_s${s}_alone=$R/bv_outlet_s$s"
done
for k in guards plain; do
    ROWS="$ROWS pf${k}_s0_auto=$F/ft_${k}_s0:guards,tolerance_r=$AUTO pf${k}_s0_alone=$F/ft_${k}_s0"
done
for k in inputs none; do
    for s in 0 1; do
        ROWS="$ROWS ft${k}_s${s}_auto=$F/ft_${k}_s$s:guards,tolerance_r=$AUTO ft${k}_s${s}_alone=$F/ft_${k}_s$s"
    done
    E=$F/ft_${k}_s0+$F/ft_${k}_s1
    ROWS="$ROWS ft${k}_e2_auto=$E:guards,tolerance_r=$AUTO ft${k}_e2_alone=$E"
done
TITLE="BendVessel, held out: the outlet recipe's seeds 0 and 1 (37 epochs) as trained, and fine-tuned from their last checkpoints for 8 epochs at lr 3e-4: with one push-forward step whose prediction is guarded (pfguards) or not (pfplain), seed 0, without the speed noise; with the input frames guarded (ftinputs) or not (ftnone), seeds 0 and 1 and their ensembles (e2); guarded at auto (0.207 r) and alone"
python $CE $OUT/heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 "$TITLE" $ROWS &
python $CE --sims-kind "validation simulation" $OUT/validation data/bendvessel.h5 bendvessel_009 \
    "BendVessel, validation: the same rows" $ROWS &
wait
L=outlet_s0_auto,outlet_s1_auto,ftnone_s0_auto,ftnone_s1_auto,ftnone_e2_auto,ftinputs_s0_auto,ftinputs_s1_auto,ftinputs_e2_auto,pfplain_s0_auto,pfguards_s0_auto
L=$L,${L//_auto/_alone}
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --out $OUT/track.md \
    $OUT/heldout $L $OUT/validation $L
