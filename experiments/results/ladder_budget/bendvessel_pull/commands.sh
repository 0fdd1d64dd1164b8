#!/bin/bash
# The commands behind this folder (2026-12-06), run from the repository root on the 2-core CPU
# (AMD EPYC), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set.
OUT=experiments/results/ladder_budget/bendvessel_pull
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s92    # the new runs (checkpoints are not committed; config.json, metrics.jsonl and
                   # loss.png are, in training/seed_*)
R90=/work/exp/s90  # the outlet recipe's seeds 0 and 1 of ../bendvessel_speed_noise/ (same data file)
R91=/work/exp/s91  # the outlet recipe's ClotEntry seeds 13 and 14 of ../clotentry_outlet/
thrombojax generate bendvessel --out data/bendvessel.h5      # fingerprint 8733d333...
# The prior alone (no model), without and with the pull
python $OUT/prior_pull.py data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 \
    0:0,0.5:0,0.5:0.111 > $OUT/prior_pull_bendvessel.md
python $OUT/prior_pull.py data/clotentry.h5 clotentry_008,clotentry_009 \
    0:0,0.5:0,0.5:0.138 > $OUT/prior_pull_clotentry.md
# The outlet recipe (the room recipe's config, split and 37 epochs with the outlet features)
# plus the centring pull, seeds 0 and 1 side by side (tolerance 0; `auto`, the median of the
# training clots' offsets, is 0.001 r on this data)
for s in 0 1; do
    thrombojax train --config experiments/results/ladder_budget/bendvessel_room/follow_room30_last/config.json \
        --dataset data/bendvessel.h5 --seed $s --outlet-features 2 --centre-pull 0.5 --out $R/bv_pull_s$s &
done; wait
# Held out and validation, alone and guarded at auto (0.2073 r); the outlet rows are copies of
# ../bendvessel_hold/'s (outlet_*_alone, outlet_*_auto), reused by cross_eval.py. The rows
# were written to /work/exp/s92/bv_eval/{heldout,validation} (OUT there) and copied here.
AUTO=0.2072737216949463
ROWS=""
for rec in outlet pull; do
    case $rec in outlet) D=$R90/bv_outlet ;; pull) D=$R/bv_pull ;; esac
    for m in s0 s1 e2; do
        case $m in e2) RUN=${D}_s0+${D}_s1 ;; *) RUN=${D}_$m ;; esac
        ROWS="$ROWS ${rec}_${m}_alone=$RUN ${rec}_${m}_auto=$RUN:guards,tolerance_r=$AUTO"
    done
done
python $CE $OUT/heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 \
    "BendVessel, held out (190 degrees outside the training rotations): the outlet recipe without and with the centring pull (--centre-pull 0.5), seeds 0 and 1 (37 epochs) and their ensemble, alone and guarded at auto (0.207 r)" $ROWS
python $CE --sims-kind "validation simulation" $OUT/validation data/bendvessel.h5 bendvessel_009 \
    "BendVessel, validation: the same rows" $ROWS
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --out $OUT/track.md \
    $OUT/heldout outlet_s0_auto,outlet_s1_auto,outlet_e2_auto,pull_s0_auto,pull_s1_auto,pull_e2_auto,outlet_s0_alone,outlet_s1_alone,outlet_e2_alone,pull_s0_alone,pull_s1_alone,pull_e2_alone \
    $OUT/validation outlet_s0_auto,outlet_s1_auto,outlet_e2_auto,pull_s0_auto,pull_s1_auto,pull_e2_auto
# ClotEntry: the 2-epoch config of ../clotentry_outlet/ with the pull at tolerance auto (the
# median, 0.138 r here), seeds 13 and 14 side by side (their first minutes beside the end of the
# BendVessel trainings)
for s in 13 14; do
    thrombojax train --config experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json \
        --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 --seed $s --select-by last \
        --outlet-features 2 --centre-pull 0.5 --centre-tolerance auto --out $R/ce_pull_s$s &
done; wait
CAUTO=0.3759514093399048
T="ClotEntry, held out"
python $CE --nodes 2048 $OUT/clotentry/a data/clotentry.h5 clotentry_008,clotentry_009 "$T" \
    p13_auto=$R/ce_pull_s13:guards,tolerance_r=$CAUTO pe2_auto=$R/ce_pull_s13+$R/ce_pull_s14:guards,tolerance_r=$CAUTO &
python $CE --nodes 2048 $OUT/clotentry/b data/clotentry.h5 clotentry_008,clotentry_009 "$T" \
    p14_auto=$R/ce_pull_s14:guards,tolerance_r=$CAUTO oe2_auto=$R91/ce_out_s13+$R91/ce_out_s14:guards,tolerance_r=$CAUTO &
wait
# Inference only: the outlet seeds 0 and 1 (trained without the pull) rolled out with the pull
# added to their prior. Each run folder is a copy of the outlet run (checkpoints linked) whose
# config.json gets train.centre_pull = 0.5, train.centre_tolerance = 0, centre_unit =
# prior_radius / 2 (a vessel radius, scaled) and centre_tolerance = 0; nothing is retrained.
for s in 0 1; do
    d=$R/infer/outlet_pull_s$s; mkdir -p $d; ln -sfn $R90/bv_outlet_s$s/checkpoints $d/checkpoints
    python - "$R90/bv_outlet_s$s/config.json" "$d/config.json" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
c["train"].update(centre_pull=0.5, centre_tolerance=0.0)
c.update(centre_unit=c["prior_radius"] / 2, centre_tolerance=0.0)
json.dump(c, open(sys.argv[2], "w"), indent=1)
PY
done
ROWS=""
for m in s0 s1 e2; do
    case $m in e2) RUN=$R/infer/outlet_pull_s0+$R/infer/outlet_pull_s1 ;; *) RUN=$R/infer/outlet_pull_$m ;; esac
    ROWS="$ROWS inferpull_${m}_alone=$RUN inferpull_${m}_auto=$RUN:guards,tolerance_r=$AUTO"
done
python $CE $OUT/inference/heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 \
    "BendVessel, held out: the outlet recipe's seeds 0 and 1 and their ensemble, trained without the pull, rolled out with --centre-pull 0.5 added to their prior (inference only), alone and guarded at auto (0.207 r)" $ROWS
python $CE --sims-kind "validation simulation" $OUT/inference/validation data/bendvessel.h5 \
    bendvessel_009 "BendVessel, validation: the same rows" $ROWS
