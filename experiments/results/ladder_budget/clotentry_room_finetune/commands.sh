#!/bin/bash
# The commands behind this folder (2026-12-05), run from the repository root on the 2-core CPU
# (Intel Xeon), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set.
# data/clotentry.h5 is `thrombojax generate clotentry --out data/clotentry.h5` on this machine;
# its fingerprint (28dd1b17..., in every training/*/config.json) is that of
# ../clotentry_budget_members/, whose 2-epoch seeds 13 and 14 the bases here repeat to the last
# digit of every logged loss.
# The room recipe's ClotEntry config (held out clotentry_008/009, validation clotentry_007,
# 2,048 nodes per sample), 2 epochs: the base. Then one epoch of the 4-step unrolled loss from
# its last checkpoint at a small learning rate: the fine-tuning. Two models side by side.
C=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
W=/work/exp/s85   # checkpoints are not committed
for pair in "13 14" "15 16"; do
    for seed in $pair; do
        thrombojax train --config $C --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 \
            --seed $seed --select-by last --out $W/base_s$seed --quiet &
    done
    wait
    for seed in $pair; do
        thrombojax train --config $W/base_s$seed/config.json --out $W/ft_s$seed \
            --init-from $W/base_s$seed --init-checkpoint last --rollout-steps 4 --epochs 1 \
            --lr 2e-5 --warmup-epochs 0.25 --select-by last --quiet &
    done
    wait
done
# The rollouts (last checkpoints, 2,048 nodes), run beside the second pair's trainings: every
# model guarded on the held-out pair; the fine-tuned ones and seed 13's base also guarded on the
# validation vessel; seed 13 (both) and seed 14 fine-tuned also alone; the four fine-tuned models
# as one guarded ensemble. Each row goes to its own <label>.json, which a second run reuses, so the
# two commands below (all rows at once) wrote every table of heldout/ and validation/ here; the
# base ensemble's row is ../clotentry_budget_members/side_by_side/e4_2ep_guards.json, copied in as
# heldout/base_e4_guards.json (the same four models, see above) before they ran.
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
OUT=experiments/results/ladder_budget/clotentry_room_finetune
ROWS="base_s13=$W/base_s13 ft_s13=$W/ft_s13 ft_s14=$W/ft_s14"
VROWS="base_s13_guards=$W/base_s13:guards"
for seed in 13 14 15 16; do
    ROWS="$ROWS base_s${seed}_guards=$W/base_s$seed:guards ft_s${seed}_guards=$W/ft_s$seed:guards"
    VROWS="$VROWS ft_s${seed}_guards=$W/ft_s$seed:guards"
done
ROWS="$ROWS base_e4_guards=$W/base_s13+$W/base_s14+$W/base_s15+$W/base_s16:guards"
ROWS="$ROWS ft_e4_guards=$W/ft_s13+$W/ft_s14+$W/ft_s15+$W/ft_s16:guards"
python $CE --nodes 2048 $OUT/heldout data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry, held out: the room recipe's 2-epoch seeds 13-16 (base) and the same after one epoch of the 4-step unrolled loss (ft)" $ROWS
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/validation data/clotentry.h5 \
    clotentry_007 "ClotEntry, validation: the same models" $VROWS
# where each clot is on its way, from the rows' JSONs alone, and the scan of every clotentry_009 row
python experiments/results/ladder_budget/clotentry_rest/track.py $OUT/track.md $OUT/heldout \
    $OUT/validation --scan experiments/results --sim clotentry_009
