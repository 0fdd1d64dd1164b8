# Four 6-epoch seeds of the default recipe as one ensemble (one rung's budget: 4 x 6 = 24 epochs
# against 25), BendVessel; Intel Xeon 2-core (family 6, model 207), jax 0.10.2, tcmalloc,
# 2026-12-03. Seeds 2 and 3 side by side, then 4 and 5 (382-405 s each); the table's rows ran
# alone (the 25-epoch rows are reused from ../bendvessel_centring/heldout/, where they were
# measured the same way on the same machine an hour before).
cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
TR=experiments/results/ladder_budget/clotentry_finetune/train_rung.py
A="--test bendvessel_005,bendvessel_012,bendvessel_019 --val bendvessel_009"
for pair in "2 3" "4 5"; do
  for s in $pair; do python $TR walk_axis /work/exp/bv6/s$s $s data/bendvessel.h5 6 $A & done; wait
done
M=/work/exp/bv6; S2=$M/s2/walk_axis/member_2/run; S3=$M/s3/walk_axis/member_3/run
S4=$M/s4/walk_axis/member_4/run; S5=$M/s5/walk_axis/member_5/run
S0=/work/exp/bv/s0/walk_axis/run; S1=/work/exp/bv/s1/walk_axis/member_1/run   # ../bendvessel_centring/
python experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py /work/exp/bv6/heldout \
  data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 \
  "BendVessel, held out (the default axis recipe: four 6-epoch seeds as one ensemble, one rung's budget, against 25-epoch seeds)" \
  e4_6ep_guards=$S2+$S3+$S4+$S5:guards m2_6ep_guards=$S2:guards m3_6ep_guards=$S3:guards \
  m4_6ep_guards=$S4:guards m5_6ep_guards=$S5:guards \
  s0_25ep_guards=$S0:guards s1_25ep_guards=$S1:guards ens2_25ep_guards=$S0+$S1:guards
