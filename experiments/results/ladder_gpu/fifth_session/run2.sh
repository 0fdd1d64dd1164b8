#!/usr/bin/env bash
# The fifth device session's second call (the device minutes left after run.sh): the small
# MeshGraphNet of the clot-wide weight recipe, seeds 0-2 trained 18 epochs each (one process
# per seed, nothing else on the GPU), then rolled out as the guarded ensemble (each member
# also guarded alone): does the rollout keep improving from 4 (CPU) to 12 (run.sh) to 18 epochs?
set -u
HERE=experiments/results/ladder_gpu/fifth_session
[ -d .whl ] && { python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir \
    --upgrade --target /tmp/site .whl/*.whl || exit 1; }
export PYTHONPATH=$PWD:/tmp/site PYTHONUNBUFFERED=1 MPLBACKEND=Agg \
    XLA_PYTHON_CLIENT_PREALLOCATE=false JAX_COMPILATION_CACHE_DIR=/tmp/jaxcache
PRESET=${PRESET:-clotentry}; TEST=${TEST:-clotentry_008,clotentry_009}; VAL=${VAL:-clotentry_007}
NODES=${NODES:-2048}; EPOCHS=${EPOCHS:-18}; LIMIT=${LIMIT:-262}
START=$(date +%s); left() { echo $(( LIMIT - $(date +%s) + START )); }
D=${D:-/root/d}; mkdir -p $D; L=$OUT/logs2; mkdir -p $L
date -u
DATA=$D/$PRESET.h5
[ -f $DATA ] || ( time python3 -m thrombojax generate $PRESET --out $DATA --quiet ) > $L/gen.log 2>&1
date -u
R=follow_nohist_cm_last
for s in 0 1 2; do
  timeout $(left) python3 $HERE/train_member.py $D/ce_small18 ${R}_ens3_guards $s $DATA $NODES \
      $TEST $VAL $EPOCHS > $L/train_$s.log 2>&1 &
done
wait; date -u
timeout $(left) python3 experiments/ladder.py --dataset $DATA --nodes $NODES --test $TEST \
    --val $VAL --epochs $EPOCHS --out $D/ce_small18 --rungs ${R}_ens3_guards \
    --title "ClotEntry (2,048 nodes), small MeshGraphNet, GPU" > $L/eval.log 2>&1
date -u
cd $D && tar czf $OUT/results18.tgz --exclude='checkpoints' --exclude='*.h5' ce_small18
tail -n 30 $L/eval.log; date -u
