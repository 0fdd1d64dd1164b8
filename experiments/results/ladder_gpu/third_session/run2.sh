#!/usr/bin/env bash
# The third device session's second call (2026-11-26): the vessel-following prior without the
# history frame (rungs follow_nohist*) and with history noise (follow_histnoise*) at the study's
# MeshGraphNet size, fixed epochs (4 on ClotEntry, 12 on BendVessel) to fit the device time left.
set -u
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=$PWD:/tmp/site PYTHONUNBUFFERED=1 MPLBACKEND=Agg \
    XLA_PYTHON_CLIENT_PREALLOCATE=false JAX_COMPILATION_CACHE_DIR=/tmp/jaxcache
D=/root/d; mkdir -p $D; L=$OUT/logs; mkdir -p $L
date -u; nvidia-smi -L
python3 -m thrombojax generate clotentry --out $D/clotentry.h5 --quiet > $L/gen_ce.log 2>&1 &
python3 -m thrombojax generate bendvessel --out $D/bendvessel.h5 --quiet > $L/gen_bv.log 2>&1 &
wait; date -u
CE="--dataset $D/clotentry.h5 --nodes 2048 --test clotentry_008,clotentry_009 --val clotentry_007"
T="ClotEntry (2,048 nodes), study MeshGraphNet (H100)"
timeout 290 python3 experiments/ladder.py $CE --epochs 4 --size study --out $D/ce_nohist \
    --rungs follow_nohist,follow_nohist_alone --title "$T" > $L/ce_nohist.log 2>&1 &
timeout 290 python3 experiments/ladder.py $CE --epochs 4 --size study --out $D/ce_histnoise \
    --rungs follow_histnoise,follow_histnoise_alone --title "$T" > $L/ce_histnoise.log 2>&1 &
timeout 290 python3 experiments/ladder.py --dataset $D/bendvessel.h5 --epochs 12 --size study \
    --out $D/bv_nohist --rungs follow_nohist,follow_nohist_alone \
    --title "BendVessel, study MeshGraphNet (H100)" > $L/bv_nohist.log 2>&1 &
wait; date -u
cd $D && tar czf $OUT/results.tgz --exclude='checkpoints' --exclude='*.h5' ce_nohist ce_histnoise bv_nohist
