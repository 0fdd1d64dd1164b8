#!/usr/bin/env bash
# The ninth device session's second call (2026-11-28): seeds 6-11 of follow_speed_last (the
# eighth session's recipe and epochs), trained side by side on the one GPU as members 6-11 of
# the rung follow_speed_last_ens12_guards, and their last checkpoints returned; the CPU then
# scores them with the eighth session's members 0-5 (one ensemble of twelve) and alone (a second
# ensemble of six). Run from the repository root with jraph and meshio wheels in .whl/ and $OUT
# set by the device tool.
set -u
TM=experiments/results/ladder_gpu/fifth_session/train_member.py
. experiments/results/ladder_gpu/device_env.sh || exit 1
PRESET=${PRESET:-clotentry}; TEST=${TEST:-clotentry_008,clotentry_009}; VAL=${VAL:-clotentry_007}
NODES=${NODES:-2048}; EPOCHS=${EPOCHS:-12}; SEEDS=${SEEDS:-6 7 8 9 10 11}
TRAIN=${TRAIN:-300}; A=follow_speed_last
START=$(date +%s); left() { echo $(( $1 - $(date +%s) + START )); }
D=${D:-/root/d}; mkdir -p $D; L=$D/logs; mkdir -p $L
date -u; nvidia-smi -L 2>/dev/null
DATA=$D/$PRESET.h5
[ -f $DATA ] || ( time python3 -m thrombojax generate $PRESET --out $DATA --quiet ) > $L/gen.log 2>&1
date -u
for s in $SEEDS; do
    timeout $(left $TRAIN) python3 $TM $D/ce ${A}_ens12_guards $s $DATA $NODES $TEST $VAL $EPOCHS \
        > $L/train_${A}_$s.log 2>&1 &
done
wait; date -u
cd $D && tar czf $OUT/ckpt.tgz $(find ce -path '*checkpoints/last' -prune) \
    $(find ce -name config.json -path '*run/*') $(find ce -name metrics.jsonl) \
    && tar czf $OUT/logs.tgz logs; cd - > /dev/null
tail -n 3 $L/*.log; ls -la $OUT; date -u
