#!/bin/bash
# The commands behind this folder (2026-12-05), run from the repository root on the 2-core CPU,
# with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set. data/clotentry.h5 is
# `thrombojax generate clotentry` (its SHA-256 is in every training/*/config.json).
# The room recipe's ClotEntry config (the ladder's follow_room30 rung with the held-out split
# clotentry_008/009, validation clotentry_007, 2,048 nodes per sample):
C=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
W=/work/exp/s83   # checkpoints are not committed
train() {  # LABEL SEED EXTRA...
    label=$1 seed=$2; shift 2
    thrombojax train --config $C --dataset data/clotentry.h5 --epochs 6 --warmup-epochs 2 \
        --seed "$seed" --select-by last --out $W/$label --quiet "$@"
}
# side by side, then the next pair side by side
train ctrl_s0 0 --skip-frames 0 & train skip40_s0 0 --skip-frames 40 & wait
train skip40_s1 1 --skip-frames 40 & train tscale13_s0 0 --time-scale 1.3 & wait
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
OUT=experiments/results/ladder_budget/clotentry_skip
for L in ctrl_s0 skip40_s0 skip40_s1 tscale13_s0; do
    python $CE --nodes 2048 $W/eval/held data/clotentry.h5 clotentry_008,clotentry_009 \
        "ClotEntry, held out" $L=$W/$L $L"_guards"=$W/$L:guards
    python $CE --nodes 2048 --sims-kind "validation simulation" $W/eval/val data/clotentry.h5 \
        clotentry_007 "ClotEntry, validation" $L"_guards"=$W/$L:guards
    python experiments/teacher_forced_accel.py --run $W/$L --dataset data/clotentry.h5 \
        --sims clotentry_008,clotentry_009 --nodes 2048 --which last --blocks 40 \
        > $OUT/teacher_forced_$L.txt
done
# the tables of all rows (each row's JSON copied in and reused, nothing rolled out again)
mkdir -p $OUT/heldout $OUT/validation
cp $W/eval/held/*.json $OUT/heldout/ && cp $W/eval/val/*.json $OUT/validation/
ROWS=""; VROWS=""
for L in ctrl_s0 skip40_s0 skip40_s1 tscale13_s0; do
    ROWS="$ROWS $L=$W/$L $L""_guards=$W/$L:guards"; VROWS="$VROWS $L""_guards=$W/$L:guards"
done
python $CE --nodes 2048 $OUT/heldout data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry, held out: the room recipe without the entry frames, and with time scaling" $ROWS
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/validation data/clotentry.h5 \
    clotentry_007 "ClotEntry, validation: the same models" $VROWS
