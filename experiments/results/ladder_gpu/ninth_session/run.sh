#!/usr/bin/env bash
# The ninth device session's call (2026-11-28, 15 device minutes): the rung follow_room_last
# (the eighth session's follow_speed_last with --wall-clot-mean: every clot node also gets the
# clot-wide mean of the clipped wall distance, the room the clot has in the vessel), seeds 0-5
# side by side on the one GPU, the small MeshGraphNet of the CPU ladder, 12 epochs as the eighth
# session; then its guarded ensemble of six, each member also scored alone guarded (one ladder
# call, the trainings' folder). Does the room, whose rollouts follow the true clot's speed on the
# CPU, bring a six-member ensemble nearer than the eighth session's 1.31 r? Run from the
# repository root with jraph and meshio wheels in .whl/ and $OUT set by the device tool. The
# logs come back as one archive (the device tool returns at most 8 files).
set -u
TM=experiments/results/ladder_gpu/fifth_session/train_member.py
. experiments/results/ladder_gpu/device_env.sh || exit 1
PRESET=${PRESET:-clotentry}; TEST=${TEST:-clotentry_008,clotentry_009}; VAL=${VAL:-clotentry_007}
NODES=${NODES:-2048}; EPOCHS=${EPOCHS:-12}; SEEDS=${SEEDS:-0 1 2 3 4 5}
LIMIT=${LIMIT:-540}; TRAIN=${TRAIN:-330}; A=${A:-follow_room_last}
START=$(date +%s); left() { echo $(( $1 - $(date +%s) + START )); }
D=${D:-/root/d}; mkdir -p $D; L=$D/logs; mkdir -p $L
date -u; nvidia-smi -L 2>/dev/null
DATA=$D/$PRESET.h5
[ -f $DATA ] || ( time python3 -m thrombojax generate $PRESET --out $DATA --quiet ) > $L/gen.log 2>&1
date -u
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
cd $D && tar czf $OUT/results.tgz --exclude='checkpoints' --exclude='*.h5' ce \
    && tar czf $OUT/logs.tgz logs; cd - > /dev/null
tail -3 $L/*.log; ls -la $OUT; date -u
