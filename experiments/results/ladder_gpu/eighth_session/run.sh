#!/usr/bin/env bash
# The eighth device session's call (2026-11-27, 15 device minutes): the rung follow_speed_last
# (the seventh session's recipe: follow_nohist_cm_last with speed noise 0.1 and wall features at
# 0.5 r), seeds 0-5 side by side on the one GPU, the small MeshGraphNet of the CPU ladder, 12
# epochs as the seventh session; then its guarded ensemble of six, each member also scored alone
# guarded (one ladder call, the trainings' folder). Does the seventh's 1.68 r hold over six seeds,
# and does a larger ensemble come nearer? Run from the repository root with jraph and meshio
# wheels in .whl/ and $OUT set by the device tool.
set -u
TM=experiments/results/ladder_gpu/fifth_session/train_member.py
. experiments/results/ladder_gpu/device_env.sh || exit 1
PRESET=${PRESET:-clotentry}; TEST=${TEST:-clotentry_008,clotentry_009}; VAL=${VAL:-clotentry_007}
NODES=${NODES:-2048}; EPOCHS=${EPOCHS:-12}; SEEDS=${SEEDS:-0 1 2 3 4 5}
LIMIT=${LIMIT:-560}; TRAIN=${TRAIN:-330}
START=$(date +%s); left() { echo $(( $1 - $(date +%s) + START )); }
D=${D:-/root/d}; mkdir -p $D; L=$OUT/logs; mkdir -p $L
date -u; nvidia-smi -L 2>/dev/null
DATA=$D/$PRESET.h5
[ -f $DATA ] || ( time python3 -m thrombojax generate $PRESET --out $DATA --quiet ) > $L/gen.log 2>&1
date -u
A=follow_speed_last
for s in $SEEDS; do
    timeout $(left $TRAIN) python3 $TM $D/ce ${A}_ens6_guards $s $DATA $NODES $TEST $VAL $EPOCHS \
        > $L/train_${A}_$s.log 2>&1 &
done
wait; date -u
cd $D && tar czf $OUT/ckpt.tgz $(find ce -path '*checkpoints/last' -prune) \
    $(find ce -name config.json -path '*run/*') $(find ce -name metrics.jsonl); cd - > /dev/null
CE="--dataset $DATA --nodes $NODES --test $TEST --val $VAL --epochs $EPOCHS"
T="ClotEntry (2,048 nodes), small MeshGraphNet, GPU"
timeout $(left $LIMIT) python3 experiments/ladder.py $CE --out $D/ce \
    --rungs ${A}_ens6_guards --title "$T" > $L/eval.log 2>&1; date -u
cd $D && tar czf $OUT/results.tgz --exclude='checkpoints' --exclude='*.h5' ce; cd - > /dev/null
ls -la $OUT; date -u
