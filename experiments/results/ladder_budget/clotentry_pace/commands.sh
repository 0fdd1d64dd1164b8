# A pace fitted on the validation vessel (clotentry_007) for one rung's ClotEntry ensembles (the
# room recipe, 2-epoch seeds); AMD EPYC 2-core (cpu family 25, model 17), jax 0.10.2, tcmalloc,
# 2026-12-04. data/clotentry.h5 is `thrombojax generate clotentry` made on this machine
# (dataset fingerprint 4b80c428... in every training/seed_*/config.json; the earlier folders'
# Intel-made file is 28dd1b17..., so these seeds are new draws, not the earlier ones retrained).
# Each JSON keeps the load it was measured at: the fits and rows ran beside trainings or the
# fresh-clone test suite.
cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
thrombojax generate clotentry --out data/clotentry.h5
# the room recipe's 2-epoch member config (../clotentry_budget_members/training/seed_13/)
CFG=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
# 1. four 2-epoch seeds at once (21:29-21:58, 28 min 49 s each), then three (21:58-22:24, 25 min
#    46 s each, beside the first fit and rows); each wave is one rung's 30 minutes
for s in 13 14 15 16; do
  thrombojax train --config $CFG --epochs 2 --warmup-epochs 0.67 --seed $s --out /work/exp/pc/s$s --quiet &
done; wait
for s in 10 11 12; do
  thrombojax train --config $CFG --epochs 2 --warmup-epochs 0.67 --seed $s --out /work/exp/pc/s$s --quiet &
done  # (the fit of step 2 ran beside them)
M=/work/exp/pc; E4=$M/s13+$M/s14+$M/s15+$M/s16; E3=$M/s10+$M/s11+$M/s12
FIT=experiments/results/ladder_budget/clotentry_pace/fit_pace.py
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
# 2. the pace of each ensemble fitted on the validation vessel clotentry_007 (fits/)
python $FIT --nodes 2048 /work/exp/pc/fit_e4.json data/clotentry.h5 clotentry_007 $E4
wait
python $FIT --nodes 2048 /work/exp/pc/fit_e3.json data/clotentry.h5 clotentry_007 $E3
# 3. the held-out vessels, guarded, without and with the fitted pace (heldout/)
python $CE --nodes 2048 /work/exp/pc/heldout data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (2-epoch seeds of the room recipe as one ensemble; pace fitted on clotentry_007)" \
  e4_guards=$E4:guards e4_pace=$E4:guards,pace=1.0868841163429424 \
  e3_guards=$E3:guards e3_pace=$E3:guards,pace=1.089175151569819 e7_guards=$E3+$E4:guards
