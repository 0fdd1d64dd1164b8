#!/bin/bash
# The commands behind this folder (2026-12-06), run from the repository root on the 2-core CPU
# (Intel Xeon), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set.
# data/clotentry.h5 is `thrombojax generate clotentry --out data/clotentry.h5` on this machine;
# its fingerprint (28dd1b17..., in every training/*/config.json) is that of
# ../clotentry_budget_members/ and ../clotentry_room_finetune/, whose 2-epoch seeds 13-16 (the
# "base" rows here) these trainings repeat: weight averaging does not touch the optimiser's
# weights, and every logged training loss is equal to the last digit.
# The room recipe's ClotEntry config (held out clotentry_008/009, validation clotentry_007,
# 2,048 nodes per sample), 2 epochs (349 steps each), the model the mean of the weights after
# each of the second epoch's steps (--average-weights 0.5). Two trainings side by side.
C=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
W=/work/exp/s86   # checkpoints are not committed
B=/work/exp/s85   # the base runs of ../clotentry_room_finetune/ (its commands.sh)
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
OUT=experiments/results/ladder_budget/clotentry_swa
for pair in "13 14" "15 16"; do
    for seed in $pair; do
        thrombojax train --config $C --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 \
            --seed $seed --select-by last --average-weights 0.5 --out $W/swa_s$seed --quiet &
    done
    wait
done
# The rollouts (last checkpoints, 2,048 nodes), guarded. Each row goes to its own <label>.json,
# which a second run of the command reuses: the base rows on the held-out pair (and base seed 13
# on the validation vessel) are ../clotentry_room_finetune/'s JSONs, copied in before these ran
# (base_e4_guards.json: the four bases as one ensemble); the command below, run again once every
# row was there, wrote the tables.
# the same rows on both kinds of simulation, base and averaged side by side; the ensembles held out
PAIRS=""
for seed in 13 14 15 16; do
    PAIRS="$PAIRS base_s${seed}_guards=$B/base_s$seed:guards swa_s${seed}_guards=$W/swa_s$seed:guards"
done
ENSEMBLES="base_e4_guards=$B/base_s13+$B/base_s14+$B/base_s15+$B/base_s16:guards \
    swa_e4_guards=$W/swa_s13+$W/swa_s14+$W/swa_s15+$W/swa_s16:guards"
python $CE --nodes 2048 $OUT/heldout data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry, held out: the room recipe's 2-epoch seeds 13-16, last weights (base) and the mean of the second epoch's weights (swa)" $ENSEMBLES $PAIRS
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/validation data/clotentry.h5 \
    clotentry_007 "ClotEntry, validation: the same models" $PAIRS
# where each clot is on its way, from the rows' JSONs alone, and the scan of every clotentry_009 row
python experiments/results/ladder_budget/clotentry_rest/track.py $OUT/track.md $OUT/heldout \
    $OUT/validation --scan experiments/results --sim clotentry_009
