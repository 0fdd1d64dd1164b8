#!/usr/bin/env bash
# The fourth device session's one call (2026-11-26, one NVIDIA H100, 15 device minutes): do the
# ClotEntry rollouts at the study's MeshGraphNet size improve with longer training? Every earlier
# ClotEntry training stopped with its loss still falling (4-10 epochs). Two ladders side by side
# on the one GPU, each with a 6-minute budget: the default recipe `axis` (rung walk_axis) and
# the vessel-following prior without the history frame (rung follow_nohist), each with its
# unguarded twin. Run from the repository root with jraph and meshio wheels in .whl/ (the
# device image lacks them) and $OUT set by the device tool.
set -u
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=$PWD:/tmp/site PYTHONUNBUFFERED=1 MPLBACKEND=Agg \
    XLA_PYTHON_CLIENT_PREALLOCATE=false JAX_COMPILATION_CACHE_DIR=/tmp/jaxcache
D=/root/d; mkdir -p $D; L=$OUT/logs; mkdir -p $L
date -u; nvidia-smi -L
( time python3 -m thrombojax generate clotentry --out $D/clotentry.h5 --quiet ) > $L/gen_ce.log 2>&1
date -u
CE="--dataset $D/clotentry.h5 --nodes 2048 --test clotentry_008,clotentry_009 --val clotentry_007"
T="ClotEntry (2,048 nodes), study MeshGraphNet (H100)"
M=${MINUTES:-6}
timeout 500 python3 experiments/ladder.py $CE --minutes $M --max-epochs 80 --size study \
    --out $D/ce_axis --rungs walk_axis,axis_alone --title "$T" > $L/ce_axis.log 2>&1 &
timeout 500 python3 experiments/ladder.py $CE --minutes $M --max-epochs 80 --size study \
    --out $D/ce_nohist --rungs follow_nohist,follow_nohist_alone --title "$T" > $L/ce_nohist.log 2>&1 &
while sleep 20; do nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader \
    >> $L/gpu.log; jobs -r | grep -q . || break; done
wait; date -u
cd $D && tar czf $OUT/results.tgz --exclude='checkpoints' --exclude='*.h5' ce_axis ce_nohist
for r in ce_axis/walk_axis ce_nohist/follow_nohist; do
    [ -d $r/run/checkpoints/best ] && tar czf $OUT/ckpt_${r%%/*}.tgz $r/run/checkpoints/best $r/run/config.json
done
ls -la $OUT; date -u
