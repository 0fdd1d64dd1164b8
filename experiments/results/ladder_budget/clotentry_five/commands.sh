# One rung's ClotEntry ensemble of five 2-epoch seeds of the room recipe, trained side by side
# within the rung's 30 minutes now that the wall searches are faster (benchmarks/wall_search.py);
# AMD EPYC 2-core (cpu family 25, model 17), jax 0.10.2, tcmalloc, 2026-12-05. data/clotentry.h5
# is the file of ../clotentry_pace/ (dataset fingerprint 4b80c428...). Each JSON keeps the load
# it was measured at.
cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
D=experiments/results/ladder_budget/clotentry_five
CFG=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
M=/work/exp/s81/runs
# 1. seeds 10-14 all at once, alone on the machine but for a few seconds of unit tests at the
#    start (07:02:36-07:31:25; 28 min 45 s to 28 min 49 s each, /usr/bin/time, in
#    training/wall_clock.md); every epoch's training loss and validation MSE equal those of
#    ../clotentry_pace/training/seed_*/metrics.jsonl to the last digit (the rewrite is exact)
for s in 10 11 12 13 14; do
  /usr/bin/time -v thrombojax train --config $CFG --dataset data/clotentry.h5 --epochs 2 \
    --warmup-epochs 0.67 --seed $s --out $M/s$s --quiet > $M/s$s.log 2>&1 &
done; wait
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
E5=$M/s10+$M/s11+$M/s12+$M/s13+$M/s14
# 2. held out, guarded, and guarded + centring 0.15 r (7 min 22 s for the two rows, alone)
python $CE --nodes 2048 $M/../five data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (2-epoch seeds of the room recipe as one ensemble)" \
  e5_guards=$E5:guards e5_centre15=$E5:guards,centring_r=0.15
# 3. the validation vessel, guarded (1 min 48 s)
python $CE --nodes 2048 --sims-kind "validation simulation" $M/../five007 data/clotentry.h5 \
  clotentry_007 "ClotEntry, validation (five 2-epoch seeds of the room recipe as one ensemble)" \
  e5_guards_007=$E5:guards
# 4. seeds 15 and 16, two at once (07:45:32-07:56:54, 11 min 20 s and 11 min 22 s), and three
#    more five-seed draws from seeds 10-16 (windows of five consecutive seeds, cyclic), guarded
#    (10 min 39 s for the three rows, alone)
for s in 15 16; do
  /usr/bin/time -v thrombojax train --config $CFG --dataset data/clotentry.h5 --epochs 2 \
    --warmup-epochs 0.67 --seed $s --out $M/s$s --quiet > $M/s$s.log 2>&1 &
done; wait
python $CE --nodes 2048 $M/../five data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (2-epoch seeds of the room recipe as one ensemble)" \
  e5b_guards=$M/s11+$M/s12+$M/s13+$M/s14+$M/s15:guards \
  e5c_guards=$M/s12+$M/s13+$M/s14+$M/s15+$M/s16:guards \
  e5d_guards=$M/s13+$M/s14+$M/s15+$M/s16+$M/s10:guards
# 4b. the other three cyclic windows (10 min 41 s for the three rows, alone)
python $CE --nodes 2048 $M/../five data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (2-epoch seeds of the room recipe as one ensemble)" \
  e5e_guards=$M/s14+$M/s15+$M/s16+$M/s10+$M/s11:guards \
  e5f_guards=$M/s15+$M/s16+$M/s10+$M/s11+$M/s12:guards \
  e5g_guards=$M/s16+$M/s10+$M/s11+$M/s12+$M/s13:guards
# 5. one table with the earlier draws of the same seeds (JSONs of ../clotentry_pace/heldout/ and
#    ../clotentry_rotations/centring/ copied into $M/../five; every row reused, nothing rolled
#    out again; R=/work/exp/rot held those runs)
R=/work/exp/rot
python $CE --nodes 2048 $M/../five data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (2-epoch seeds of the room recipe as one ensemble)" \
  e3_guards=$R/s10+$R/s11+$R/s12:guards e4_guards=$R/s13+$R/s14+$R/s15+$R/s16:guards \
  e5_guards=$E5:guards e5b_guards=$M/s11+$M/s12+$M/s13+$M/s14+$M/s15:guards \
  e5c_guards=$M/s12+$M/s13+$M/s14+$M/s15+$M/s16:guards \
  e5d_guards=$M/s13+$M/s14+$M/s15+$M/s16+$M/s10:guards \
  e5e_guards=$M/s14+$M/s15+$M/s16+$M/s10+$M/s11:guards \
  e5f_guards=$M/s15+$M/s16+$M/s10+$M/s11+$M/s12:guards \
  e5g_guards=$M/s16+$M/s10+$M/s11+$M/s12+$M/s13:guards \
  e7_guards=$R/s10+$R/s11+$R/s12+$R/s13+$R/s14+$R/s15+$R/s16:guards \
  e3_centre15=$R/s10+$R/s11+$R/s12:guards,centring_r=0.15 \
  e4_centre15=$R/s13+$R/s14+$R/s15+$R/s16:guards,centring_r=0.15 \
  e5_centre15=$E5:guards,centring_r=0.15
mkdir -p $D/heldout $D/validation
cp $M/../five/e5*.json $M/../five/table.md $M/../five/ladder.json $M/../five/error_per_step.png \
   $D/heldout/
cp $M/../five007/* $D/validation/
# (e3/e4/e7 rows: ../clotentry_pace/heldout/; e3/e4 with centring: ../clotentry_rotations/centring/)
