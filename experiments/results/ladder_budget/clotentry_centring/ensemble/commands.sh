# The four seeds of ../heldout/commands.sh (trained there) as one ensemble; Intel Xeon 2-core
# (family 6, model 207), jax 0.10.2, tcmalloc; the two held-out rows ran side by side, then the
# validation rows beside two single-seed rows (load 2-5; each row's JSON keeps its environment).
cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
E=/work/exp/rm/s0/follow_room30_last/run+/work/exp/rm/s1/follow_room30_last/member_1/run
E=$E+/work/exp/rm/s2/follow_room30_last/member_2/run+/work/exp/rm/s3/follow_room30_last/member_3/run
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
# the held-out pair (table.md, ladder.json, error_per_step.png, ens4_*.json here)
python $CE --nodes 2048 /work/exp/ctr/ens4 data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (the room recipe, seeds 0-3 trained on Intel, as an ensemble, with and without centring)" \
  ens4_guards=$E:guards ens4_centre15=$E:guards,centring_r=0.15
# the validation simulation (validation/)
python $CE --nodes 2048 /work/exp/ctr/ens4_val data/clotentry.h5 clotentry_007 \
  "ClotEntry, validation simulation (the room recipe, seeds 0-3 trained on Intel, as an ensemble, with and without centring)" \
  ens4_guards=$E:guards ens4_centre15=$E:guards,centring_r=0.15
# the same ensemble from the command line (cli/): an ensemble folder of the four runs
mkdir -p /work/exp/rm/ens4 && cd /work/exp/rm/ens4
ln -sfn /work/exp/rm/s0/follow_room30_last/run member_0
for s in 1 2 3; do ln -sfn /work/exp/rm/s$s/follow_room30_last/member_$s/run member_$s; done
echo '{"members": ["member_0", "member_1", "member_2", "member_3"], "seeds": [0, 1, 2, 3], "model": "mgn"}' > ensemble.json
cd /work/main
thrombojax rollout --run /work/exp/rm/ens4 --dataset data/clotentry.h5 --sim clotentry_008 \
  --sim clotentry_009 --checkpoint last --centring 0.15 --out /work/exp/ctr/cli_ens4_centre15
# every three of the four as an ensemble, with centring (three/; run at nice 19 beside the
# fresh-clone test suite, then alone)
S0=/work/exp/rm/s0/follow_room30_last/run; S1=/work/exp/rm/s1/follow_room30_last/member_1/run
S2=/work/exp/rm/s2/follow_room30_last/member_2/run; S3=/work/exp/rm/s3/follow_room30_last/member_3/run
python $CE --nodes 2048 /work/exp/ctr/ens3 data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out (the room recipe, every three of seeds 0-3 as an ensemble, with centring)" \
  ens_123_centre15=$S1+$S2+$S3:guards,centring_r=0.15 ens_023_centre15=$S0+$S2+$S3:guards,centring_r=0.15 \
  ens_013_centre15=$S0+$S1+$S3:guards,centring_r=0.15 ens_012_centre15=$S0+$S1+$S2:guards,centring_r=0.15
