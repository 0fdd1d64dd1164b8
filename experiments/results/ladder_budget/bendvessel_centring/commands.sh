# The centring guard on BendVessel (2026-12-03): Intel Xeon 2-core (family 6, model 207), jax
# 0.10.2, tcmalloc. The two trainings ran side by side (1,664 s and 1,658 s for 25 epochs);
# the held-out rows ran alone, then the ClotEntry command-line rollout beside them (load 2.5-5).
cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
thrombojax generate bendvessel --out data/bendvessel.h5   # 38 s
# 1. where the true clot lies (truth_offset.*, no model)
names=$(python -c "from thrombojax.io.hdf5 import open_dataset; print(','.join(open_dataset('data/bendvessel.h5').names))")
python experiments/results/ladder_budget/clotentry_centring/truth_offset.py \
  experiments/results/ladder_budget/bendvessel_centring/truth_offset data/bendvessel.h5 $names
# 2. the default recipe (rung walk_axis = thrombojax train --recipe axis), seeds 0 and 1, 25 epochs
#    (training/seed_*/ holds each config.json and metrics.jsonl)
TR=experiments/results/ladder_budget/clotentry_finetune/train_rung.py
for s in 0 1; do
  python $TR walk_axis /work/exp/bv/s$s $s data/bendvessel.h5 25 \
    --test bendvessel_005,bendvessel_012,bendvessel_019 --val bendvessel_009 &
done; wait
# 3. guarded, with and without centring (0.08 r: the training simulations' 95th percentile;
#    0.15 r: ClotEntry's), each seed and the two as an ensemble (heldout/)
S0=/work/exp/bv/s0/walk_axis/run; S1=/work/exp/bv/s1/walk_axis/member_1/run
python experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py /work/exp/bv/heldout \
  data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 \
  "BendVessel, held out (the default axis recipe, seeds 0-1, 25 epochs, with and without centring)" \
  s0_guards=$S0:guards s0_centre08=$S0:guards,centring_r=0.08 s0_centre15=$S0:guards,centring_r=0.15 \
  s1_guards=$S1:guards s1_centre08=$S1:guards,centring_r=0.08 s1_centre15=$S1:guards,centring_r=0.15 \
  ens2_guards=$S0+$S1:guards ens2_centre08=$S0+$S1:guards,centring_r=0.08 \
  ens2_centre15=$S0+$S1:guards,centring_r=0.15
# 4. from the command line: the two runs joined, rolled out with --centring auto and without
#    (cli_auto/, cli_guards/)
thrombojax ensemble $S0 $S1 --out /work/exp/bv/ens2 --checkpoint last
thrombojax rollout --run /work/exp/bv/ens2 --dataset data/bendvessel.h5 --checkpoint last \
  --centring auto --out /work/exp/bv/cli_ens2_auto --quiet
thrombojax rollout --run /work/exp/bv/ens2 --dataset data/bendvessel.h5 --checkpoint last \
  --out /work/exp/bv/cli_ens2_guards --quiet
# 5. ClotEntry's four-seed ensemble (../clotentry_centring/) with --centring auto
#    (../clotentry_centring/ensemble/cli_auto/)
thrombojax ensemble /work/exp/rm/s0/follow_room30_last/run /work/exp/rm/s1/follow_room30_last/member_1/run \
  /work/exp/rm/s2/follow_room30_last/member_2/run /work/exp/rm/s3/follow_room30_last/member_3/run \
  --out /work/exp/rm/ens4_joined --checkpoint last
thrombojax rollout --run /work/exp/rm/ens4_joined --dataset data/clotentry.h5 --sim clotentry_008 \
  --sim clotentry_009 --checkpoint last --centring auto --out /work/exp/ctr/cli_ens4_auto --quiet
