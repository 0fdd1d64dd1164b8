#!/usr/bin/env bash
# The seventh device session's call (2026-11-27, 15 device minutes): the rung follow_speed_last
# (ClotEntry's clot-wide weight recipe, follow_nohist_cm_last, with speed noise 0.1 and wall
# features at 0.5 r; experiments/results/clot_speed/: the true clot returns within a few frames
# to the speed its room in the vessel allows), seeds 0-2 side by side on the one GPU, the small
# MeshGraphNet of the CPU ladder, 12 epochs as the fifth session's control; then its guarded
# ensemble of three and the three alone (one ladder call, the trainings' folder). Run from the repository root with jraph and meshio
# wheels in .whl/ and $OUT set by the device tool.
set -u
TM=experiments/results/ladder_gpu/fifth_session/train_member.py
. experiments/results/ladder_gpu/device_env.sh || exit 1
PRESET=${PRESET:-clotentry}; TEST=${TEST:-clotentry_008,clotentry_009}; VAL=${VAL:-clotentry_007}
NODES=${NODES:-2048}; EPOCHS=${EPOCHS:-12}
LIMIT=${LIMIT:-540}; TRAIN=${TRAIN:-400}
START=$(date +%s); left() { echo $(( $1 - $(date +%s) + START )); }
D=${D:-/root/d}; mkdir -p $D; L=$OUT/logs; mkdir -p $L
date -u; nvidia-smi -L 2>/dev/null
DATA=$D/$PRESET.h5
[ -f $DATA ] || ( time python3 -m thrombojax generate $PRESET --out $DATA --quiet ) > $L/gen.log 2>&1
date -u
A=follow_speed_last
for s in 0 1 2; do
    timeout $(left $TRAIN) python3 $TM $D/ce ${A}_seeds3 $s $DATA $NODES $TEST $VAL $EPOCHS \
        > $L/train_${A}_$s.log 2>&1 &
done
wait; date -u
cd $D && tar czf $OUT/ckpt.tgz $(find ce -path '*checkpoints/last' -prune) \
    $(find ce -name config.json -path '*run/*') $(find ce -name metrics.jsonl); cd - > /dev/null
CE="--dataset $DATA --nodes $NODES --test $TEST --val $VAL --epochs $EPOCHS"
T="ClotEntry (2,048 nodes), small MeshGraphNet, GPU"
timeout $(left $LIMIT) python3 experiments/ladder.py $CE --out $D/ce \
    --rungs ${A}_ens3_guards,${A}_seeds3 --title "$T" > $L/eval.log 2>&1; date -u
cd $D && tar czf $OUT/results.tgz --exclude='checkpoints' --exclude='*.h5' ce; cd - > /dev/null
ls -la $OUT; date -u
