cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
A=/work/exp/rm/s0/follow_room30_last/run
time nice -n 10 .venv/bin/python experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py --nodes 2048 \
  /work/exp/ctr/ho_rm data/clotentry.h5 clotentry_008,clotentry_009 "ClotEntry, held out (the room recipe, seed 0, with and without centring)" \
  rm_s0_centre15=$A:guards,centring_r=0.15 rm_s0_guards=$A:guards
