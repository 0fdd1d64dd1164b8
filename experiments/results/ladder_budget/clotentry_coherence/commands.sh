#!/bin/bash
# The commands behind this folder (2026-12-06), run from the repository root on the 2-core CPU
# (Intel Xeon), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set.
# No training: the models are the room recipe's 2-epoch seeds 13-16 of
# ../clotentry_room_finetune/ (the "base" runs; its commands.sh trained them), on
# data/clotentry.h5 (fingerprint 28dd1b17..., `thrombojax generate clotentry`).
# Their rows at the default coherence tolerance (1 r) are that folder's
# heldout/base_s1[3-6]_guards.json and base_e4_guards.json and ../clotentry_swa/'s
# validation/base_s1[3-6]_guards.json, copied in before the rows below were measured; the
# four bases' ensemble on clotentry_007 at the default (validation/base_e4_guards.json) was
# measured here.
B=/work/exp/s85   # the base runs (checkpoints are not committed)
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
OUT=experiments/results/ladder_budget/clotentry_coherence
# The true clot against a rigid copy of its rollout start (no model)
python $OUT/truth_deviation.py $OUT/truth_deviation.md data/clotentry.h5
# Each base guarded with the coherence tolerance at 0.7, 0.5, 0.3 and 0.15 r (tolerance_r, a
# keyword of thrombojax.simulator.guard_set.build_guards; `thrombojax rollout
# --coherence-tolerance R`), the four as one ensemble at 0.5, 0.3 and 0.15 r. The rows ran as ten
# cross_eval.py processes, two at a time, each into a folder of its own; their
# JSONs were then copied into heldout/ and validation/ and the two commands below, run once
# every row was there, wrote the tables (a row's JSON is reused, not measured again).
ROWS="base_e4_guards=$B/base_s13+$B/base_s14+$B/base_s15+$B/base_s16:guards \
    base_e4_coh05=$B/base_s13+$B/base_s14+$B/base_s15+$B/base_s16:guards,tolerance_r=0.5 \
    base_e4_coh03=$B/base_s13+$B/base_s14+$B/base_s15+$B/base_s16:guards,tolerance_r=0.3 \
    base_e4_coh015=$B/base_s13+$B/base_s14+$B/base_s15+$B/base_s16:guards,tolerance_r=0.15"
for seed in 13 14 15 16; do
    ROWS="$ROWS base_s${seed}_guards=$B/base_s$seed:guards"
    for t in 7 5 3 15; do ROWS="$ROWS base_s${seed}_coh0$t=$B/base_s$seed:guards,tolerance_r=0.$t"; done
done
python $CE --nodes 2048 $OUT/heldout data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry, held out: the room recipe's 2-epoch seeds 13-16, guarded, the coherence tolerance at 1 (default), 0.7, 0.5, 0.3 and 0.15 r" $ROWS
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/validation data/clotentry.h5 \
    clotentry_007 "ClotEntry, validation: the same rows" $ROWS
# where each clot is on its way, from the rows' JSONs alone
python experiments/results/ladder_budget/clotentry_rest/track.py $OUT/track.md $OUT/heldout $OUT/validation
