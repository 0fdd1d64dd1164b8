#!/usr/bin/env bash
# The third device session's one call (2026-11-26, one NVIDIA H100, 15 device minutes): the
# `axis` recipe (the default of `thrombojax train`) and it with the vessel-following prior
# (`--follow-axis 2`, rungs follow / follow_alone) at the study's MeshGraphNet size, trained
# on the device, three ladders side by side on the one GPU. Run from the repository root with
# jraph and meshio wheels in .whl/ (the device image lacks them) and $OUT set by the device tool.
set -u
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=$PWD:/tmp/site PYTHONUNBUFFERED=1 MPLBACKEND=Agg \
    XLA_PYTHON_CLIENT_PREALLOCATE=false JAX_COMPILATION_CACHE_DIR=/tmp/jaxcache
D=/root/d; mkdir -p $D; L=$OUT/logs; mkdir -p $L
date -u; nvidia-smi -L
( time python3 -m thrombojax generate clotentry --out $D/clotentry.h5 --quiet ) > $L/gen_ce.log 2>&1 &
( time python3 -m thrombojax generate bendvessel --out $D/bendvessel.h5 --quiet ) > $L/gen_bv.log 2>&1 &
wait; date -u; tail -4 $L/gen_*.log
CE="--dataset $D/clotentry.h5 --nodes 2048 --test clotentry_008,clotentry_009 --val clotentry_007"
M=${MINUTES:-3}
timeout 400 python3 experiments/ladder.py $CE --minutes $M --max-epochs 60 --size study \
    --out $D/ce_axis --rungs walk_axis,axis_alone \
    --title "ClotEntry (2,048 nodes), study MeshGraphNet (H100)" > $L/ce_axis.log 2>&1 &
timeout 400 python3 experiments/ladder.py $CE --minutes $M --max-epochs 60 --size study \
    --out $D/ce_follow --rungs follow,follow_alone \
    --title "ClotEntry (2,048 nodes), study MeshGraphNet (H100)" > $L/ce_follow.log 2>&1 &
timeout 400 python3 experiments/ladder.py --dataset $D/bendvessel.h5 --minutes $M \
    --max-epochs 60 --size study --out $D/bv_follow --rungs follow,follow_alone \
    --title "BendVessel, study MeshGraphNet (H100)" > $L/bv_follow.log 2>&1 &
while sleep 20; do nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader \
    >> $L/gpu.log; jobs -r | grep -q . || break; done
wait; date -u; tail -3 $L/*.log
cd $D && tar czf $OUT/results.tgz --exclude='checkpoints' --exclude='*.h5' ce_axis ce_follow bv_follow
ls -la $OUT
