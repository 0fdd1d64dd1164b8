set -u
. experiments/results/ladder_gpu/device_env.sh || exit 1
START=$(date +%s); L=$OUT/logs; mkdir -p $L; D=/root/d; mkdir -p $D; cp -r .gl/ce $D/ce
date -u; ( time python3 -m thrombojax generate clotentry --out $D/clotentry.h5 --quiet ) > $L/gen.log 2>&1; date -u
TM=experiments/results/ladder_gpu/fifth_session/train_member.py
for a in "follow_kstep_last_seeds3 0 8" "follow_kstep_last_seeds3 2 8" "follow_kstep6_last_seeds3 0 6" "follow_kstep6_last_seeds3 2 6"; do
  set -- $a
  timeout $(( 265 - $(date +%s) + START )) python3 $TM $D/ce $1 $2 $D/clotentry.h5 2048 clotentry_008,clotentry_009 clotentry_007 $3 > $L/resume_$1_$2.log 2>&1 &
done
wait; date -u
cd $D && tar czf $OUT/ckpt2.tgz $(find ce -path '*checkpoints/last' -prune) $(find ce -name config.json -path '*run/*') $(find ce -name metrics.jsonl)
date -u
