#!/bin/bash
# The commands behind this folder (2026-12-06/07), run from the repository root on the 2-core CPU
# (AMD EPYC), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set.
# Nothing is trained here: the outlet recipe's ClotEntry seeds 13-16 of ../clotentry_outlet/
# (2 epochs each; checkpoints are not committed, their config.json, metrics.jsonl and loss.png
# are in ../clotentry_outlet/training/) are rolled out with the vessel-following prior's
# centring pull set at rollout time, the setting chosen on BendVessel beforehand (strength 0.5;
# the tolerance `auto`, the median offset of the training clots from the vessel's middle, 0.138 r
# for seed 13's training simulations at 2,048 nodes, as ../bendvessel_pull/'s ClotEntry runs
# fitted it). thrombojax rollout --centre-pull 0.5 does the same for one run or ensemble folder.
OUT=experiments/results/ladder_budget/rollout_pull
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s91    # the outlet seeds' run folders
CAUTO=0.3759514093399048   # the coherence guard's auto tolerance on ClotEntry (r)
PT=0.13841405510902405     # the pull's auto tolerance (r)
P=centre_pull=0.5,centre_tolerance_r=$PT
E4=$R/ce_out_s13+$R/ce_out_s14+$R/ce_out_s15+$R/ce_out_s16
# The outlet rows (outlet_s13..16, outlet_e4) are copies of ../clotentry_outlet/heldout/'s,
# reused by cross_eval.py; the rows with the pull were measured in two processes into
# /work/exp/s93/ce/{a,b} and copied here, then the table written from all of them:
ROWS=""
for s in 13 14 15 16; do
  ROWS="$ROWS outlet_s$s=$R/ce_out_s$s:guards,tolerance_r=$CAUTO pull_s$s=$R/ce_out_s$s:guards,tolerance_r=$CAUTO,$P"
done
python $CE --nodes 2048 $OUT/clotentry data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out: the outlet recipe's 2-epoch seeds 13-16 (trained without the pull) rolled out without and with the centring pull set at rollout time (0.5, tolerance 0.138 r, the auto median of seed 13's training clots), each alone and the four as one ensemble, guarded at auto (0.376 r), and the ensemble without the guards" \
  $ROWS outlet_e4=$E4:guards,tolerance_r=$CAUTO pull_e4=$E4:guards,tolerance_r=$CAUTO,$P \
  outlet_e4_alone=$E4 pull_e4_alone=$E4:alone,$P
# BendVessel: the same pull at rollout time on the outlet seeds 0 and 1 is
# ../bendvessel_pull/inference/ (measured there through copies of the runs' config.json; the
# step is the same, the pull's unit the vessel radius, tolerance 0, `auto` being 0.001 r there).
# The same through the command line, seed 13 on clotentry_008 (cli_seed13_clotentry_008.md is
# its rollout.md; the tolerance is fitted by --centre-tolerance's default, auto):
thrombojax rollout --run $R/ce_out_s13 --dataset data/clotentry.h5 --sim clotentry_008 --nodes 2048 \
  --checkpoint last --coherence-tolerance $CAUTO --centre-pull 0.5 --no-gif --out /work/exp/s93/cli_ce13
# The validation vessel (clotentry_007), the ensemble at strengths 0, 0.25, 0.5 and 1 (measured
# in two processes into /work/exp/s93/cev/{a,b}, copied here, the table written from all four):
V=""
for k in 025:0.25 050:0.5 100:1.0; do
  V="$V pull${k%%:*}_e4=$E4:guards,tolerance_r=$CAUTO,centre_pull=${k##*:},centre_tolerance_r=$PT"
done
# and each seed alone without and with 0.5 (into /work/exp/s93/cev2/{a,b}, copied here too):
S=""
for s in 13 14 15 16; do
  S="$S outlet_s$s=$R/ce_out_s$s:guards,tolerance_r=$CAUTO pull050_s$s=$R/ce_out_s$s:guards,tolerance_r=$CAUTO,$P"
done
python $CE --nodes 2048 --sims-kind "validation simulation" $OUT/clotentry_validation data/clotentry.h5 \
  clotentry_007 "ClotEntry, validation: the outlet recipe's seeds 13-16 alone and as one ensemble, guarded at auto (0.376 r), without the pull and with it set at rollout time (0.5; the ensemble also at 0.25 and 1; tolerance 0.138 r)" \
  $S outlet_e4=$E4:guards,tolerance_r=$CAUTO $V
