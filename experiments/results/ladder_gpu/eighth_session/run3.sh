#!/usr/bin/env bash
# The eighth device session's third call, on the machine run2.sh left warm (its dataset and the
# members' runs in /root/d): the same six members scored again as independent guarded rollouts
# (the ensemble of run.sh, on the regenerated dataset) and as a committee without the guards.
# The command as it was run (one line in the call), with the line breaks added.
. experiments/results/ladder_gpu/device_env.sh; D=/root/d
ls $D >/dev/null 2>&1 || { echo "not warm"; exit 3; }
timeout 220 python3 experiments/ladder.py --dataset $D/clotentry.h5 --nodes 2048 \
    --test clotentry_008,clotentry_009 --val clotentry_007 --epochs 12 --out $D/ce \
    --rungs follow_speed_last_ens6_guards,follow_speed_last_committee6 \
    --title "ClotEntry (2,048 nodes), small MeshGraphNet, GPU" > $OUT/eval3.log 2>&1
cd $D && tar czf $OUT/results3.tgz --exclude='checkpoints' --exclude='*.h5' ce
tail -12 $OUT/eval3.log
