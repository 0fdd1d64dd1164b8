#!/bin/bash
# The commands behind this folder (2026-12-07), run from the repository root on the 2-core CPU
# (AMD EPYC), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set.
OUT=experiments/results/ladder_budget/bendvessel_exit
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R90=/work/exp/s90  # the outlet recipe's seeds 0 and 1 of ../bendvessel_speed_noise/ (37 epochs)
R=/work/exp/s94    # the new runs (checkpoints are not committed; config.json, metrics.jsonl and
                   # loss.png are, in training/)
AUTO=0.2072737216949463  # the fitted coherence tolerance (r), the default of thrombojax rollout
# rows LABEL RUNPREFIX: seeds 0, 1 (RUNPREFIX_s0, _s1) and their ensemble (e2), alone and at auto
rows() {
    for m in s0 s1 e2; do
        case $m in e2) RUN=$2_s0+$2_s1 ;; *) RUN=$2_$m ;; esac
        echo -n " $1_${m}_alone=$RUN $1_${m}_auto=$RUN:guards,tolerance_r=$AUTO"
    done
}
thrombojax generate bendvessel --out data/bendvessel.h5      # fingerprint 8733d333...

# 1. The true clot's exit, per simulation (no model)
python $OUT/exit_truth.py data/bendvessel.h5 --held-out bendvessel_005,bendvessel_012,bendvessel_019 \
    --validation bendvessel_009 --steady 0.1 \
    --out $OUT/exit_truth.md

# 2. Each guard alone, and the containment margin, on the outlet ensemble (seeds 0 + 1). The
# outlet_e2_alone / _auto rows are copies of ../bendvessel_speed_noise/'s, reused.
E2=$R90/bv_outlet_s0+$R90/bv_outlet_s1
GUARD_ROWS="outlet_e2_cohonly=$E2:guards,containment=0,tolerance_r=$AUTO outlet_e2_contonly=$E2:guards,coherence=0
    outlet_e2_m05=$E2:guards,margin_r=0.05,tolerance_r=$AUTO outlet_e2_m10=$E2:guards,margin_r=0.1,tolerance_r=$AUTO
    outlet_e2_m20=$E2:guards,margin_r=0.2,tolerance_r=$AUTO"

# 3. Unrolled fine-tuning of the outlet seeds: 3 epochs of a 4-step loss at lr 2e-5, side by side
for s in 0 1; do
    thrombojax train --config $R90/bv_outlet_s$s/config.json --dataset data/bendvessel.h5 \
        --init-from $R90/bv_outlet_s$s --init-checkpoint last --rollout-steps 4 --epochs 3 \
        --lr 2e-5 --warmup-epochs 0.25 --select-by last --out $R/ft/k4_s$s &
done; wait
FT_ROWS=$(rows ftk4 $R/ft/k4)

# 4. The outlet recipe with the speed noise on steady windows only, seeds 0 and 1 side by side
# (--speed-noise-steady was then at its first version, see README.md)
for s in 0 1; do
    thrombojax train --config experiments/results/ladder_budget/bendvessel_room/follow_room30_last/config.json \
        --dataset data/bendvessel.h5 --seed $s --outlet-features 2 --speed-noise-steady 0.1 \
        --out $R/gate/bv_s$s &
done; wait
ST_ROWS=$(rows steady $R/gate/bv)
OUTLET_ROWS=$(rows outlet $R90/bv_outlet)
# The rows were computed in /work/exp/s94 (several invocations, OUT there) and copied here;
# cross_eval.py reuses every OUT/<label>.json, so these two commands rebuild the tables:
python $CE $OUT/heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 \
    "BendVessel, held out (190 degrees outside the training rotations): the outlet recipe's seeds 0 and 1 (37 epochs) and their ensemble (outlet), each guard alone and the containment margin on the ensemble, after 3 epochs of a 4-step loss (ftk4), and trained with the speed noise on steady windows only (steady, --speed-noise-steady 0.1); alone and guarded at auto (0.207 r)" \
    $OUTLET_ROWS $FT_ROWS $ST_ROWS $GUARD_ROWS outlet_e2_t05=$E2:guards,tol_r=0.05,tolerance_r=$AUTO
python $CE --sims-kind "validation simulation" $OUT/validation data/bendvessel.h5 bendvessel_009 \
    "BendVessel, validation: the same rows" $OUTLET_ROWS $FT_ROWS $ST_ROWS $GUARD_ROWS
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --out $OUT/track.md \
    $OUT/heldout outlet_s0_auto,outlet_s1_auto,outlet_e2_auto,outlet_e2_cohonly,outlet_e2_contonly,outlet_e2_m05,outlet_e2_m10,outlet_e2_m20,outlet_e2_t05,ftk4_s0_auto,ftk4_s1_auto,ftk4_e2_auto,steady_s0_auto,steady_s1_auto,steady_e2_auto,outlet_s0_alone,outlet_s1_alone,outlet_e2_alone,ftk4_s0_alone,ftk4_s1_alone,ftk4_e2_alone,steady_s0_alone,steady_s1_alone,steady_e2_alone \
    $OUT/validation outlet_s0_auto,outlet_s1_auto,outlet_e2_auto,outlet_e2_cohonly,outlet_e2_contonly,outlet_e2_m05,outlet_e2_m10,outlet_e2_m20,ftk4_s0_auto,ftk4_s1_auto,ftk4_e2_auto,steady_s0_auto,steady_s1_auto,steady_e2_auto,outlet_e2_alone,steady_e2_alone
# Teacher-forced: what the steady-noise steps make of the true frames in the exit
python experiments/results/ladder_budget/bendvessel_shapes/exit/exit_teacher.py $OUT/exit_teacher_steady.json \
    data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 steady_s0=$R/gate/bv_s0 steady_s1=$R/gate/bv_s1

# 5. ClotEntry: the 2-epoch outlet config of ../clotentry_outlet/ with --speed-noise-steady 0.1,
# seeds 13 and 14 side by side; held out (008, 009), 2,048 nodes, guarded at auto (0.376 r)
thrombojax generate clotentry --out data/clotentry.h5          # fingerprint 4b80c428...
for s in 13 14; do
    thrombojax train --config experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json \
        --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 --seed $s --select-by last \
        --outlet-features 2 --speed-noise-steady 0.1 --out $R/gate/ce_s$s &
done; wait
CAUTO=0.3759514093399048
R91=/work/exp/s91  # the outlet recipe's ClotEntry seeds of ../clotentry_outlet/; its rows
                   # outlet_s13_auto, outlet_s14_auto (and outlet_e2_auto, ../bendvessel_pull/'s
                   # run of the pair) are copies, reused
python $CE --nodes 2048 $OUT/clotentry data/clotentry.h5 clotentry_008,clotentry_009 \
    "ClotEntry, held out: the outlet recipe's 2-epoch seeds 13 and 14 and their ensemble, as trained (outlet) and with the speed noise on steady windows only (steady, --speed-noise-steady 0.1), guarded at auto (0.376 r)" \
    outlet_s13_auto=$R91/ce_out_s13:guards,tolerance_r=$CAUTO outlet_s14_auto=$R91/ce_out_s14:guards,tolerance_r=$CAUTO \
    outlet_e2_auto=$R91/ce_out_s13+$R91/ce_out_s14:guards,tolerance_r=$CAUTO \
    steady_s13_auto=$R/gate/ce_s13:guards,tolerance_r=$CAUTO steady_s14_auto=$R/gate/ce_s14:guards,tolerance_r=$CAUTO \
    steady_e2_auto=$R/gate/ce_s13+$R/gate/ce_s14:guards,tolerance_r=$CAUTO
