# Three 2-epoch seeds of the room recipe as one ensemble (one rung's budget: 3 x 2 = 6 epochs),
# ClotEntry; Intel Xeon 2-core (family 6, model 207), jax 0.10.2, tcmalloc, 2026-12-03. The
# three trained at once beside a fresh-clone `make test` (load about 7; 2,077-2,147 s each); the
# rows ran after them, the first two beside the end of that test suite (each row's JSON keeps
# its load).
cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
# the room recipe's run config (../clotentry_centring/training/seed_0/config.json: the recipe
# follow_room30_last, 6 epochs, warm-up 2 epochs) with 2 epochs and the warm-up scaled with them
RUN0=/work/exp/rm/s0/follow_room30_last/run
for s in 10 11 12; do
  thrombojax train --config $RUN0/config.json --epochs 2 --warmup-epochs 0.67 --seed $s \
    --out /work/exp/ce3/s$s --quiet &
done; wait
M=/work/exp/ce3; E=$M/s10+$M/s11+$M/s12
python experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py --nodes 2048 \
  /work/exp/ce3/heldout data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (the room recipe: three 2-epoch seeds as one ensemble, one rung's budget)" \
  e3_2ep_centre15=$E:guards,centring_r=0.15 e3_2ep_guards=$E:guards \
  m10_2ep_centre15=$M/s10:guards,centring_r=0.15 m11_2ep_centre15=$M/s11:guards,centring_r=0.15 \
  m12_2ep_centre15=$M/s12:guards,centring_r=0.15
