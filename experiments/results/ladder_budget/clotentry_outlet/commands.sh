#!/bin/bash
# The commands behind this folder (2026-12-06), run from the repository root on the 2-core CPU
# (AMD EPYC), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set.
OUT=experiments/results/ladder_budget/clotentry_outlet
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s91    # the new runs (checkpoints are not committed; config.json and metrics.jsonl
                   # are, in training/seed_*)
R89=/work/exp/s89  # the room recipe's seeds 13-16 of ../coherence_auto/ (same data file)
thrombojax generate clotentry --out data/clotentry.h5        # fingerprint 4b80c428... (this CPU)
# The room recipe's 2-epoch seeds (the config of ../clotentry_budget_members/) with the outlet
# features, the seeds of ../coherence_auto/'s ClotEntry rows; 13 and 14 at once, then 15 and 16
# (729-731 s each; the room seeds took 670-672 s the same way).
for s in 13 14 15 16; do
    thrombojax train --config experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json \
        --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 --seed $s --select-by last \
        --outlet-features 2 --out $R/ce_out_s$s
done
# Held out, 2,048 nodes, guarded at auto (0.3760 r, ../coherence_auto/fit_table.md): each new
# seed alone and the four as one ensemble, measured by two cross_eval.py processes side by side
# (o13-o15; o16 and the ensemble) into folders of their own. Their JSONs were copied into
# heldout/ as outlet_*.json, beside ../coherence_auto/clotentry_heldout/'s s*_auto.json and
# e4_auto.json as room_*.json (the same seeds without the feature), and the command below, with
# every row there, wrote the table.
CAUTO=0.3759514093399048
ROWS=""
for s in 13 14 15 16; do
    ROWS="$ROWS room_s$s=$R89/ce_s$s:guards,tolerance_r=$CAUTO outlet_s$s=$R/ce_out_s$s:guards,tolerance_r=$CAUTO"
done
E=$R89/ce_s13+$R89/ce_s14+$R89/ce_s15+$R89/ce_s16
F=$R/ce_out_s13+$R/ce_out_s14+$R/ce_out_s15+$R/ce_out_s16
ROWS="$ROWS room_e4=$E:guards,tolerance_r=$CAUTO outlet_e4=$F:guards,tolerance_r=$CAUTO"
python $CE --nodes 2048 $OUT/heldout data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry, held out: the room recipe's 2-epoch seeds 13-16 without and with the outlet features (--outlet-features 2), each alone and the four as one ensemble, guarded at auto (0.376 r)" $ROWS
