# How to split one rung's budget over ensemble members on ClotEntry (the room recipe); Intel Xeon
# 2-core (family 6, model 207), jax 0.10.2, tcmalloc, 2026-12-03. Each row's JSON keeps the load
# it was measured at; one_epoch/e6_1ep_guards.json was measured while three more 1-epoch seeds
# (not used, stopped) trained beside it.
cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
# the room recipe's run config (../clotentry_centring/training/seed_0/config.json: the recipe
# follow_room30_last, 6 epochs, warm-up 2 epochs); epochs and warm-up changed, nothing else
RUN0=/work/exp/rm/s0/follow_room30_last/run
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
# 1. six 1-epoch seeds, two waves of three at once (19:32-19:53, 21.5 minutes in all)
for wave in "20 21 22" "23 24 25"; do
  for s in $wave; do
    thrombojax train --config $RUN0/config.json --epochs 1 --warmup-epochs 0.33 --seed $s \
      --out /work/exp/ce6/s$s --quiet &
  done; wait
done
M=/work/exp/ce6
python $CE --nodes 2048 /work/exp/ce6/heldout data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (the room recipe: six 1-epoch seeds as one ensemble, one rung's budget)" \
  e6_1ep_guards=$M/s20+$M/s21+$M/s22+$M/s23+$M/s24+$M/s25:guards
# 2. four 2-epoch seeds, all four at once (20:15-20:41, 26 minutes), alone on the machine; the
# seven-member row joins them to the three 2-epoch seeds of ../clotentry_budget_ensemble/
for s in 13 14 15 16; do
  thrombojax train --config $RUN0/config.json --epochs 2 --warmup-epochs 0.67 --seed $s \
    --out /work/exp/ce4/s$s --quiet &
done; wait
M=/work/exp/ce4; P=/work/exp/ce3; E=$M/s13+$M/s14+$M/s15+$M/s16
python $CE --nodes 2048 /work/exp/ce4/heldout data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (the room recipe: four 2-epoch seeds trained side by side as one ensemble, one rung's 30 minutes)" \
  e4_2ep_guards=$E:guards e7_2ep_guards=$P/s10+$P/s11+$P/s12+$E:guards
# 3. the same two ensembles with centring at 0.15 r (beside a fresh-clone `make test`)
python $CE --nodes 2048 /work/exp/ce4/heldout data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (the room recipe: four 2-epoch seeds trained side by side as one ensemble, one rung's 30 minutes)" \
  e4_2ep_guards=$E:guards e7_2ep_guards=$P/s10+$P/s11+$P/s12+$E:guards \
  e4_2ep_centre15=$E:guards,centring_r=0.15 e7_2ep_centre15=$P/s10+$P/s11+$P/s12+$E:guards,centring_r=0.15
