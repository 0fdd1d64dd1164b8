cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
R=/work/exp/cl/s0/follow_clear30_last/run
time .venv/bin/python experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py --nodes 2048 --sims-kind "validation simulation" \
  /work/exp/ctr/val_cl data/clotentry.h5 clotentry_007 "ClotEntry validation clotentry_007 (clearance recipe, seed 0): the centring tolerance" \
  cl_s0_guards=$R:guards cl_s0_centre35=$R:guards,centring_r=0.35 cl_s0_centre15=$R:guards,centring_r=0.15
