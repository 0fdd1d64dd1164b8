#!/usr/bin/env bash
# The fifth device session's one call (2026-11-27, 15 device minutes): ClotEntry with the
# clot-wide error weight (rungs follow_nohist_cm_last*: the vessel-following prior, no history
# frame, --clot-mean-weight 10, last checkpoint), which gave the best small CPU rollout yet
# (seed 0, 4 epochs: 1.91 r) but a 1.9-9.5 r spread over seeds 0-2 with the validation loss
# still falling at epoch 4. Two questions, side by side on the one GPU:
#   small: the CPU ladder's small MeshGraphNet, seeds 0-2, each trained 3x as long (12 epochs;
#          one process per seed), then evaluated alone, guarded and as a guarded ensemble;
#   study: the study's MeshGraphNet, seed 0, a 4.5-minute budget, alone and guarded.
# Run from the repository root with jraph and meshio wheels in .whl/ (the device image lacks
# them) and $OUT set by the device tool. PRESET/TEST/VAL/NODES/EPOCHS/MINUTES/LIMIT override
# the defaults for a smoke test on the tiny preset.
set -u
HERE=experiments/results/ladder_gpu/fifth_session
if [ -d .whl ]; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site .whl/*.whl || exit 1
fi
export PYTHONPATH=$PWD:/tmp/site PYTHONUNBUFFERED=1 MPLBACKEND=Agg \
    XLA_PYTHON_CLIENT_PREALLOCATE=false JAX_COMPILATION_CACHE_DIR=/tmp/jaxcache
PRESET=${PRESET:-clotentry}; TEST=${TEST:-clotentry_008,clotentry_009}; VAL=${VAL:-clotentry_007}
NODES=${NODES:-2048}; EPOCHS=${EPOCHS:-12}; MINUTES=${MINUTES:-4.5}; LIMIT=${LIMIT:-520}  # seconds from the start for everything but the packing
START=$(date +%s); left() { echo $(( LIMIT - $(date +%s) + START )); }
D=${D:-/root/d}; mkdir -p $D; L=$OUT/logs; mkdir -p $L
date -u; nvidia-smi -L 2>/dev/null
DATA=$D/$PRESET.h5
[ -f $DATA ] || ( time python3 -m thrombojax generate $PRESET --out $DATA --quiet ) > $L/gen.log 2>&1
date -u
CE="--dataset $DATA --nodes $NODES --test $TEST --val $VAL"
T="ClotEntry (2,048 nodes), study MeshGraphNet ($(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1))"
R=follow_nohist_cm_last
timeout $(left) python3 experiments/ladder.py $CE --minutes $MINUTES --max-epochs 60 --size study \
    --out $D/ce_study --rungs $R,${R}_guards --title "$T" > $L/study.log 2>&1 &
# small: member 0 by the ladder, members 1 and 2 beside it, then the ladder evaluates
(
  timeout $(left) python3 experiments/ladder.py $CE --epochs $EPOCHS --out $D/ce_small \
      --rungs $R --title "ClotEntry (2,048 nodes), small MeshGraphNet, GPU" > $L/small_0.log 2>&1 &
  for s in 1 2; do
    timeout $(left) python3 $HERE/train_member.py $D/ce_small ${R}_seeds3 $s $DATA $NODES \
        $TEST $VAL $EPOCHS > $L/small_$s.log 2>&1 &
  done
  wait
  timeout $(left) python3 experiments/ladder.py $CE --epochs $EPOCHS --out $D/ce_small \
      --rungs $R,${R}_guards,${R}_ens3_guards,${R}_seeds3 \
      --title "ClotEntry (2,048 nodes), small MeshGraphNet, GPU" > $L/small_eval.log 2>&1
) &
while sleep 15; do
  { date -u +%T; nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader 2>/dev/null
    cat /proc/loadavg; } | tr '\n' ' ' >> $L/gpu.log; echo >> $L/gpu.log
  jobs -r | grep -q . || break
done
wait; date -u
cd $D && tar czf $OUT/results.tgz --exclude='checkpoints' --exclude='*.h5' ce_study ce_small
tar czf $OUT/ckpt.tgz $(find ce_study ce_small -path '*checkpoints/last' -prune) \
    $(find ce_study ce_small -name config.json -path '*run/*')
ls -la $OUT; date -u
