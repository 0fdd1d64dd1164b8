#!/usr/bin/env bash
# The eighth device session's second call: the six members of run.sh (their last checkpoints,
# carried back as data/ckpt8.tgz) rolled out as a committee, guarded: every step the members'
# mean prediction, guarded, is fed back to all (rung follow_speed_last_committee6_guards). The
# dataset is generated again; the script prints whether it is the one the members trained on
# (the run's dataset fingerprint). The members' runs keep only their last checkpoint, which is
# linked as "best" so that the ladder finds them finished instead of resuming them. Run from the
# repository root with jraph and meshio wheels in .whl/ and $OUT set by the device tool.
set -u
. experiments/results/ladder_gpu/device_env.sh || exit 1
PRESET=${PRESET:-clotentry}; TEST=${TEST:-clotentry_008,clotentry_009}; VAL=${VAL:-clotentry_007}
NODES=${NODES:-2048}; EPOCHS=${EPOCHS:-12}; LIMIT=${LIMIT:-300}
START=$(date +%s); left() { echo $(( $1 - $(date +%s) + START )); }
D=${D:-/root/d}; mkdir -p $D; L=$OUT/logs; mkdir -p $L
date -u; nvidia-smi -L 2>/dev/null
DATA=$D/$PRESET.h5
[ -f $DATA ] || ( time python3 -m thrombojax generate $PRESET --out $DATA --quiet ) > $L/gen2.log 2>&1
tar xzf data/ckpt8.tgz -C $D || exit 1
for c in $(find $D/ce -type d -name checkpoints); do [ -e $c/best ] || ln -s last $c/best; done
python3 - $DATA $D/ce/follow_speed_last/run/config.json > $L/fingerprint.log 2>&1 <<'PY'
import json, sys
from thrombojax.io.hdf5 import open_dataset
from thrombojax.train.guards import dataset_fingerprint
new = dataset_fingerprint(open_dataset(sys.argv[1]))["sha256"]
old = json.load(open(sys.argv[2]))["dataset_fingerprint"]["sha256"]
print(f"regenerated dataset {new}\nthe members' dataset {old}\nsame data: {new == old}")
PY
date -u
CE="--dataset $DATA --nodes $NODES --test $TEST --val $VAL --epochs $EPOCHS"
T="ClotEntry (2,048 nodes), small MeshGraphNet, GPU"
timeout $(left $LIMIT) python3 experiments/ladder.py $CE --out $D/ce \
    --rungs follow_speed_last_committee6_guards --title "$T" > $L/eval2.log 2>&1; date -u
cd $D && tar czf $OUT/results2.tgz --exclude='checkpoints' --exclude='*.h5' ce; cd - > /dev/null
ls -la $OUT; date -u
