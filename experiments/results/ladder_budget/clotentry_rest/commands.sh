#!/bin/bash
# The commands behind this folder (2026-12-05), run from the repository root on the 2-core CPU,
# with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set. data/clotentry.h5 is
# `thrombojax generate clotentry`, the same file as ../clotentry_skip/ (its SHA-256 is in every
# training/*/config.json).
# The room recipe's ClotEntry config (the ladder's follow_room30 rung with the held-out split
# clotentry_008/009, validation clotentry_007, 2,048 nodes per sample), plus --rest-edges:
C=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
W=/work/exp/s84   # checkpoints are not committed
# two side by side (seeds 0 and 1), then the next two side by side (seeds 2 and 3)
for pair in "0 1" "2 3"; do
    for seed in $pair; do
        thrombojax train --config $C --dataset data/clotentry.h5 --epochs 6 --warmup-epochs 2 \
            --seed $seed --select-by last --out $W/rest_s$seed --quiet --rest-edges &
    done
    wait
done
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
OUT=experiments/results/ladder_budget/clotentry_rest
evaluate() {  # LABEL: held out alone and guarded, validation guarded, teacher-forced (two at once)
    L=$1
    python $CE --nodes 2048 $W/eval_$L/held data/clotentry.h5 clotentry_008,clotentry_009 \
        "ClotEntry, held out" $L=$W/$L $L"_guards"=$W/$L:guards
    python $CE --nodes 2048 --sims-kind "validation simulation" $W/eval_$L/val \
        data/clotentry.h5 clotentry_007 "ClotEntry, validation" $L"_guards"=$W/$L:guards
    python experiments/teacher_forced_accel.py --run $W/$L --dataset data/clotentry.h5 \
        --sims clotentry_008,clotentry_009 --nodes 2048 --which last --blocks 40 \
        > $OUT/teacher_forced_$L.txt
}
evaluate rest_s0 & evaluate rest_s1 & wait
evaluate rest_s2 & evaluate rest_s3 & wait
# the four as one guarded ensemble, held out and validation
E4=$W/rest_s0+$W/rest_s1+$W/rest_s2+$W/rest_s3
python $CE --nodes 2048 $W/eval_e4/held data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry, held out" rest_e4_guards=$E4:guards &
python $CE --nodes 2048 --sims-kind "validation simulation" $W/eval_e4/val data/clotentry.h5 \
    clotentry_007 "ClotEntry, validation" rest_e4_guards=$E4:guards & wait
# the tables of all rows, with the same day's control (ctrl_s0 of ../clotentry_skip/, the recipe
# without --rest-edges, seed 0, on the same file): each row's JSON copied in and reused, nothing
# rolled out again
SKIP=experiments/results/ladder_budget/clotentry_skip
mkdir -p $OUT/heldout $OUT/validation
cp $SKIP/heldout/ctrl_s0.json $SKIP/heldout/ctrl_s0_guards.json $OUT/heldout/
cp $SKIP/validation/ctrl_s0_guards.json $OUT/validation/
for d in $W/eval_*/; do cp ${d}held/*_*.json $OUT/heldout/; cp ${d}val/*_guards.json $OUT/validation/; done
R0=/work/exp/s83/ctrl_s0  # where ../clotentry_skip/ trained it
ROWS="ctrl_s0=$R0 ctrl_s0_guards=$R0:guards"; VROWS="ctrl_s0_guards=$R0:guards"
for L in rest_s0 rest_s1 rest_s2 rest_s3; do
    ROWS="$ROWS $L=$W/$L $L""_guards=$W/$L:guards"; VROWS="$VROWS $L""_guards=$W/$L:guards"
done
ROWS="$ROWS rest_e4_guards=$E4:guards"; VROWS="$VROWS rest_e4_guards=$E4:guards"
python $CE --nodes 2048 $OUT/heldout data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry, held out: the room recipe with the clot's rest state on its edges" $ROWS
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/validation data/clotentry.h5 \
    clotentry_007 "ClotEntry, validation: the same models" $VROWS
# where each clot is on its way (largest centroid error over the rollout, speed per block), read
# from the rows' JSONs, with the earlier room-recipe rows of the same split beside them
python $OUT/track.py $OUT/track.md $OUT/heldout $OUT/validation \
    experiments/results/ladder_budget/clotentry_five/heldout \
    experiments/results/ladder_budget/clotentry_five/validation \
    --scan experiments/results --sim clotentry_009
