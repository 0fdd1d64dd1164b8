# Intel Xeon 2-core (family 6, model 207), jax 0.10.2, tcmalloc; seeds 0-3 of the room recipe
# trained on this machine (training/seed_*/config.json; two at a time, 50-64 min each beside
# another training and evaluations), then every row below (a row's JSON is reused when the
# command runs again; the rows were measured by several runs of this command, two at a time).
cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
TR=experiments/results/ladder_budget/clotentry_finetune/train_rung.py
SPLIT="--test clotentry_008,clotentry_009 --val clotentry_007 --nodes 2048"
for s in 0 1 2 3; do python $TR follow_room30_last /work/exp/rm/s$s $s data/clotentry.h5 6 $SPLIT; done
S0=/work/exp/rm/s0/follow_room30_last/run
S1=/work/exp/rm/s1/follow_room30_last/member_1/run
S2=/work/exp/rm/s2/follow_room30_last/member_2/run
S3=/work/exp/rm/s3/follow_room30_last/member_3/run
time python experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py --nodes 2048 \
  /work/exp/ctr/ho_rm data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (the room recipe, seeds 0-3 trained on Intel, with and without centring)" \
  rm_s0_centre15=$S0:guards,centring_r=0.15 rm_s0_guards=$S0:guards \
  rm_s1_guards=$S1:guards rm_s1_centre15=$S1:guards,centring_r=0.15 \
  rm_s2_guards=$S2:guards rm_s3_guards=$S3:guards \
  rm_s2_centre15=$S2:guards,centring_r=0.15 rm_s3_centre15=$S3:guards,centring_r=0.15
