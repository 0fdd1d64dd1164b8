#!/bin/bash
# The commands behind this folder (2026-12-07), run from the repository root on the 2-core CPU
# (AMD EPYC), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set.
OUT=experiments/results/ladder_budget/bendvessel_exit_levers
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s95    # the new runs (checkpoints are not committed; config.json, metrics.jsonl and
                   # loss.png are, in training/)
R90=/work/exp/s90  # ../bendvessel_speed_noise/'s outlet seeds 0 and 1 (37 epochs)
R94=/work/exp/s94  # ../bendvessel_exit/'s --speed-noise-steady 0.1 seeds 0 and 1
AUTO=0.2072737216949463  # the fitted coherence tolerance (r), the default of thrombojax rollout
ROOM=experiments/results/ladder_budget/bendvessel_room/follow_room30_last/config.json
# rows LABEL RUNPREFIX: seeds 0, 1 (RUNPREFIX_s0, _s1) and their ensemble (e2), alone and at auto
rows() {
    for m in s0 s1 e2; do
        case $m in e2) RUN=$2_s0+$2_s1 ;; *) RUN=$2_$m ;; esac
        echo -n " $1_${m}_alone=$RUN $1_${m}_auto=$RUN:guards,tolerance_r=$AUTO"
    done
}
thrombojax generate bendvessel --out data/bendvessel.h5      # fingerprint 8733d333...

# 1. A history frame with the speed noise on steady windows only, seeds 0 and 1 side by side
for s in 0 1; do
    thrombojax train --config $ROOM --dataset data/bendvessel.h5 --seed $s --outlet-features 2 \
        --history 2 --speed-noise-steady 0.1 --out $R/hist/bv_s$s &
done; wait

# 2. The windows --speedup-weight weighs up (no model), then the outlet recipe with them
# weighted 1 + 3 in the loss, seeds 0 and 1 side by side
python $OUT/speedup_windows.py data/bendvessel.h5 --held-out bendvessel_005,bendvessel_012,bendvessel_019 \
    --validation bendvessel_009 --weight 3 --fraction 0.1 --out $OUT/speedup_windows.md
for s in 0 1; do
    thrombojax train --config $ROOM --dataset data/bendvessel.h5 --seed $s --outlet-features 2 \
        --speedup-weight 3 --out $R/sw/bv_s$s &
done; wait

# 3. Evaluation: held out (005, 012, 019) and validation (009), alone and guarded at auto. The
# outlet_* and steady_* rows are copies of ../bendvessel_exit/'s, reused (cross_eval.py reuses
# every OUT/<label>.json).
# The *_keep rows: the three ensembles guarded with coherence keeping the clot's centroid
KEEP="outlet_e2_keep=$R90/bv_outlet_s0+$R90/bv_outlet_s1:guards,tolerance_r=$AUTO,keep_centroid=1
    steady_e2_keep=$R94/gate/bv_s0+$R94/gate/bv_s1:guards,tolerance_r=$AUTO,keep_centroid=1
    speedup_e2_keep=$R/sw/bv_s0+$R/sw/bv_s1:guards,tolerance_r=$AUTO,keep_centroid=1"
# Each guard alone on the speed-up ensemble
ONE="speedup_e2_cohonly=$R/sw/bv_s0+$R/sw/bv_s1:guards,containment=0,tolerance_r=$AUTO
    speedup_e2_contonly=$R/sw/bv_s0+$R/sw/bv_s1:guards,coherence=0"
ROWS="$(rows outlet $R90/bv_outlet) $(rows steady $R94/gate/bv) $(rows hist $R/hist/bv) $(rows speedup $R/sw/bv) $KEEP $ONE"
python $CE $OUT/heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 \
    "BendVessel, held out (190 degrees outside the training rotations): the outlet recipe (outlet), with the speed noise on steady windows only (steady, --speed-noise-steady 0.1), with a history frame as well (hist, --history 2 --speed-noise-steady 0.1) and with the windows whose clot speeds up weighted 1 + 3 in the loss (speedup, --speedup-weight 3); seeds 0 and 1 (37 epochs) and their ensemble, alone and guarded at auto (0.207 r); *_keep: the ensembles guarded with coherence keeping the clot's centroid (keep_centroid); speedup_e2_cohonly / _contonly: each guard alone" $ROWS
python $CE --sims-kind "validation simulation" $OUT/validation data/bendvessel.h5 bendvessel_009 \
    "BendVessel, validation: the same rows" $ROWS
L=outlet_s0_auto,outlet_s1_auto,outlet_e2_auto,steady_s0_auto,steady_s1_auto,steady_e2_auto,hist_s0_auto,hist_s1_auto,hist_e2_auto,speedup_s0_auto,speedup_s1_auto,speedup_e2_auto,outlet_e2_keep,steady_e2_keep,speedup_e2_keep,speedup_e2_cohonly,speedup_e2_contonly,outlet_e2_alone,steady_e2_alone,hist_e2_alone,speedup_s0_alone,speedup_s1_alone,speedup_e2_alone
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --out $OUT/track.md \
    $OUT/heldout $L $OUT/validation $L
# Teacher-forced: what the speed-up-weighted steps make of the true frames in the exit
python experiments/results/ladder_budget/bendvessel_shapes/exit/exit_teacher.py $OUT/exit_teacher_speedup.json \
    data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 speedup_s0=$R/sw/bv_s0 speedup_s1=$R/sw/bv_s1
