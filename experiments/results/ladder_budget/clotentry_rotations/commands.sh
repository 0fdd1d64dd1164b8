# One rung's ClotEntry ensembles (the room recipe, 2-epoch seeds) rolled out on turned copies
# of each held-out vessel (a rotation ensemble: cross_eval.py's `rotations=4`, the same as
# `thrombojax rollout --rotations 4`); AMD EPYC 2-core (cpu family 25, model 17), jax 0.10.2,
# tcmalloc, 2026-12-05. data/clotentry.h5 is the file of ../clotentry_pace/ (dataset
# fingerprint 4b80c428...). Each JSON keeps the load it was measured at.
cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
D=experiments/results/ladder_budget/clotentry_rotations
# the room recipe's 2-epoch member config (../clotentry_budget_members/training/seed_13/)
CFG=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
# 1. ../clotentry_pace/'s seeds again: four at once (03:34-04:00, 26 min 05 s each, alone),
#    then three (04:25-04:50, 24 min 50 s each, beside the rules of ../../follow_axis/clotentry_pace/); every
#    epoch's training loss equals the one in ../clotentry_pace/training/seed_*/metrics.jsonl
#    to the last digit, so these are those models (same data, seeds and code path)
for s in 13 14 15 16; do
  thrombojax train --config $CFG --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 \
    --seed $s --out /work/exp/rot/s$s --quiet &
done; wait
for s in 10 11 12; do
  thrombojax train --config $CFG --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 \
    --seed $s --out /work/exp/rot/s$s --quiet &
done; wait
M=/work/exp/rot; E4=$M/s13+$M/s14+$M/s15+$M/s16; E3=$M/s10+$M/s11+$M/s12
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
T="ClotEntry, held out (2-epoch seeds of the room recipe as one ensemble, on turned copies)"
# 2. every member on 4 copies of each vessel (the first unturned), guarded: 16 and 12 rollouts
#    per vessel in one compiled program (14 min 11 s for the four seeds, 10 min 54 s for the three, alone)
python $CE --nodes 2048 $M/heldout data/clotentry.h5 clotentry_008,clotentry_009 "$T" \
  e4_rot4_guards=$E4:guards,rotations=4
python $CE --nodes 2048 $M/heldout data/clotentry.h5 clotentry_008,clotentry_009 "$T" \
  e3_rot4_guards=$E3:guards,rotations=4
# 3. one table beside the same ensembles unturned (../clotentry_pace/heldout/e3_guards.json and
#    e4_guards.json copied in; every row's JSON is reused, nothing rolled out again)
cp experiments/results/ladder_budget/clotentry_pace/heldout/e3_guards.json \
   experiments/results/ladder_budget/clotentry_pace/heldout/e4_guards.json $M/heldout/
python $CE --nodes 2048 $M/heldout data/clotentry.h5 clotentry_008,clotentry_009 "$T" \
  e3_guards=$E3:guards e3_rot4_guards=$E3:guards,rotations=4 \
  e4_guards=$E4:guards e4_rot4_guards=$E4:guards,rotations=4
mkdir -p $D/heldout
cp $M/heldout/e3_rot4_guards.json $M/heldout/e4_rot4_guards.json $M/heldout/table.md \
   $M/heldout/ladder.json $M/heldout/error_per_step.png $D/heldout/
# (the e3_guards / e4_guards rows are ../clotentry_pace/heldout/'s files, not copied here)
# 4. the same two ensembles, unturned, with the centring guard at 0.15 r (centring/; 7 min 9 s
#    for both rows, alone), and the three-seed one on the validation vessel clotentry_007
#    (centring/validation/)
python $CE --nodes 2048 $M/centre data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (2-epoch seeds of the room recipe as one ensemble, centring 0.15 r)" \
  e3_centre15=$E3:guards,centring_r=0.15 e4_centre15=$E4:guards,centring_r=0.15
python $CE --nodes 2048 --sims-kind "validation simulation" $M/centre007 data/clotentry.h5 clotentry_007 \
  "ClotEntry, validation (three 2-epoch seeds of the room recipe as one ensemble, centring 0.15 r)" \
  e3_centre15_007=$E3:guards,centring_r=0.15
mkdir -p $D/centring/validation
cp $M/centre/e3_centre15.json $M/centre/e4_centre15.json $M/centre/table.md $M/centre/ladder.json \
   $M/centre/error_per_step.png $D/centring/
cp $M/centre007/* $D/centring/validation/
