#!/usr/bin/env bash
# The sixth device session's call (2026-11-27, 15 device minutes): ClotEntry's best recipe so far
# (follow_nohist_cm_last: the vessel-following prior, no history frame, the clot-wide error
# weighted 10x, last checkpoint) with the k-step unrolled loss, which no ClotEntry run had
# combined with it. A rollout's clot drifts off the track by an error it integrates step after
# step; with k > 1 the loss sees that drift (each step's target brings the rollout back onto the
# true frame) and its gradients run through the steps. Two recipes, seeds 0-2 each, all six
# trainings side by side on the one GPU, the small MeshGraphNet of the CPU ladder:
#   follow_kstep_last:  one push-forward step, then 3 steps with gradients (k grown over 3 epochs)
#   follow_kstep6_last: 6 steps with gradients, no push-forward (k grown over 3 epochs)
# then each recipe's guarded ensemble of three (each member also scored guarded), as far as the
# time allows; the checkpoints come back either way (the CPU scores the rest).
# Run from the repository root with jraph and meshio wheels in .whl/ (the device image lacks
# them) and $OUT set by the device tool. PRESET/TEST/VAL/NODES/EPOCHS_A/EPOCHS_B/LIMIT/TRAIN
# override the defaults for a smoke test on the tiny preset.
set -u
TM=experiments/results/ladder_gpu/fifth_session/train_member.py
. experiments/results/ladder_gpu/device_env.sh || exit 1
PRESET=${PRESET:-clotentry}; TEST=${TEST:-clotentry_008,clotentry_009}; VAL=${VAL:-clotentry_007}
NODES=${NODES:-2048}; EPOCHS_A=${EPOCHS_A:-8}; EPOCHS_B=${EPOCHS_B:-6}
LIMIT=${LIMIT:-480}  # seconds from the start for everything but the packing
TRAIN=${TRAIN:-330}  # seconds from the start by which the trainings must end
START=$(date +%s); left() { echo $(( $1 - $(date +%s) + START )); }
D=${D:-/root/d}; mkdir -p $D; L=$OUT/logs; mkdir -p $L
date -u; nvidia-smi -L 2>/dev/null
DATA=$D/$PRESET.h5
[ -f $DATA ] || ( time python3 -m thrombojax generate $PRESET --out $DATA --quiet ) > $L/gen.log 2>&1
date -u
A=follow_kstep_last; B=follow_kstep6_last
for s in 0 1 2; do
    timeout $(left $TRAIN) python3 $TM $D/ce ${A}_seeds3 $s $DATA $NODES $TEST $VAL $EPOCHS_A \
        > $L/train_${A}_$s.log 2>&1 &
    timeout $(left $TRAIN) python3 $TM $D/ce ${B}_seeds3 $s $DATA $NODES $TEST $VAL $EPOCHS_B \
        > $L/train_${B}_$s.log 2>&1 &
done
monitor() { while sleep 15; do
    { date -u +%T; nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader \
        2>/dev/null; cat /proc/loadavg; } | tr '\n' ' ' >> $L/gpu.log; echo >> $L/gpu.log
done; }
monitor & MON=$!
wait $(jobs -p | grep -v "^$MON$"); date -u
cd $D && tar czf $OUT/ckpt.tgz $(find ce -path '*checkpoints/last' -prune) \
    $(find ce -name config.json -path '*run/*') $(find ce -name metrics.jsonl); cd - > /dev/null
CE="--dataset $DATA --nodes $NODES --test $TEST --val $VAL"
for R in $A $B; do
    E=$([ $R = $A ] && echo $EPOCHS_A || echo $EPOCHS_B)
    timeout $(left $LIMIT) python3 experiments/ladder.py $CE --epochs $E --out $D/ce \
        --rungs ${R}_ens3_guards --title "ClotEntry (2,048 nodes), small MeshGraphNet, GPU" \
        > $L/eval_$R.log 2>&1 &
done
wait $(jobs -p | grep -v "^$MON$"); kill $MON; date -u
cd $D && tar czf $OUT/results.tgz --exclude='checkpoints' --exclude='*.h5' ce
ls -la $OUT; date -u
