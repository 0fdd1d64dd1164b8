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
