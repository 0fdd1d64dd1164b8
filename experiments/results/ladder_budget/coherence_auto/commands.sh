#!/bin/bash
# The commands behind this folder (2026-12-06), run from the repository root on the 2-core CPU
# (AMD EPYC), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set.
OUT=experiments/results/ladder_budget/coherence_auto
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s89   # the runs (checkpoints are not committed; config.json and metrics.jsonl are)
thrombojax generate bendvessel --out data/bendvessel.h5      # fingerprint 8733d333...
thrombojax generate clotentry --out data/clotentry.h5        # fingerprint 4b80c428... (this CPU)
# What `auto` fits on each dataset's training simulations (no model)
python $OUT/fit_table.py $OUT/fit_table.md \
    experiments/results/ladder_budget/bendvessel_room/follow_room30_last/config.json=data/bendvessel.h5 \
    experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json=data/clotentry.h5
# Two seeds of the room recipe on BendVessel with the ladder's split and budget (the config of
# ../bendvessel_room/, 37 epochs; the two trained at once)
for s in 0 1; do
    thrombojax train --config experiments/results/ladder_budget/bendvessel_room/follow_room30_last/config.json \
        --dataset data/bendvessel.h5 --seed $s --out $R/bv_room_s$s &
done; wait
# Rolled out at their last checkpoints: alone, guarded at the default coherence tolerance (1 r),
# at 0.5, 0.3, auto (0.2073 r, fit_table.md) and 0.15 r; the two as one ensemble likewise
AUTO=0.2072737216949463
ROWS=""
for m in s0 s1 e2; do
    case $m in e2) RUN=$R/bv_room_s0+$R/bv_room_s1 ;; *) RUN=$R/bv_room_$m ;; esac
    ROWS="$ROWS ${m}_alone=$RUN ${m}_guards=$RUN:guards ${m}_coh05=$RUN:guards,tolerance_r=0.5 \
        ${m}_coh03=$RUN:guards,tolerance_r=0.3 ${m}_auto=$RUN:guards,tolerance_r=$AUTO \
        ${m}_coh015=$RUN:guards,tolerance_r=0.15"
done
python $CE $OUT/bendvessel_heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 \
    "BendVessel, held out (190 degrees outside the training rotations): the room recipe's seeds 0 and 1 (37 epochs) and their ensemble, alone and guarded at coherence tolerances 1 (default), 0.5, 0.3, auto (0.207) and 0.15 r" $ROWS
python $CE --sims-kind "validation simulation" $OUT/bendvessel_validation data/bendvessel.h5 \
    bendvessel_009 "BendVessel, validation: the same rows" $ROWS
# The two as one ensemble folder, rolled out by `thrombojax rollout` with no tolerance given
# (the default, auto; coherence_fit in cli_default/rollout.json)
thrombojax ensemble $R/bv_room_s0 $R/bv_room_s1 --out $R/bv_e2
thrombojax rollout --run $R/bv_e2 --dataset data/bendvessel.h5 --checkpoint last --no-gif --out $OUT/cli_default
# ClotEntry: four 2-epoch seeds of the room recipe (the config of ../clotentry_budget_members/),
# two at a time, on this machine's file; rolled out on the held-out pair at 1 r and at auto
# (0.3760 r, fit_table.md), each alone and the four as one ensemble. The rows ran as three
# cross_eval.py processes into folders of their own, two at a time; their JSONs were copied into
# clotentry_heldout/ and the command below, run once every row was there, wrote the table.
for s in 13 14 15 16; do   # 13 and 14 at once, then 15 and 16
    thrombojax train --config experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json \
        --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 --seed $s --select-by last --out $R/ce_s$s
done
CAUTO=0.3759514093399048
E4=$R/ce_s13+$R/ce_s14+$R/ce_s15+$R/ce_s16
ROWS="e4_guards=$E4:guards e4_auto=$E4:guards,tolerance_r=$CAUTO"
for s in 13 14 15 16; do ROWS="$ROWS s${s}_guards=$R/ce_s$s:guards s${s}_auto=$R/ce_s$s:guards,tolerance_r=$CAUTO"; done
python $CE --nodes 2048 $OUT/clotentry_heldout data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry, held out: the room recipe's 2-epoch seeds 13-16 and their ensemble, guarded at the coherence tolerance 1 r (the default before) and auto (0.376 r)" $ROWS
