#!/bin/bash
# The commands behind this folder (2026-12-06), run from the repository root on the 2-core CPU
# (AMD EPYC), with LD_PRELOAD=libtcmalloc_minimal.so.4 and JAX_COMPILATION_CACHE_DIR set.
OUT=experiments/results/ladder_budget/bendvessel_hold
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
R=/work/exp/s91    # the new runs (checkpoints are not committed; config.json and metrics.jsonl
                   # are, in training/seed_*)
R90=/work/exp/s90  # the outlet recipe's seeds 0 and 1 of ../bendvessel_speed_noise/ (same data file)
thrombojax generate bendvessel --out data/bendvessel.h5      # fingerprint 8733d333...
# The outlet recipe (the room recipe's config, split and 37 epochs with the outlet features)
# plus the lateral hold, seeds 0 and 1 side by side, niced under the ClotEntry work of
# ../clotentry_outlet/ and stopped (kill -STOP) while ../../demo/'s two demos ran.
for s in 0 1; do
    nice -n 10 thrombojax train --config experiments/results/ladder_budget/bendvessel_room/follow_room30_last/config.json \
        --dataset data/bendvessel.h5 --seed $s --outlet-features 2 --lateral-hold 2 --out $R/bv_hold_s$s &
done; wait
# Held out and validation, alone and guarded at auto (0.2073 r); the outlet rows are copies of
# ../bendvessel_speed_noise/'s (outlet_*_alone, outlet_*_auto), reused by cross_eval.py. The
# rows were written to /work/exp/s91/bv_eval/{heldout,validation} (OUT there) and copied here.
AUTO=0.2072737216949463
ROWS=""
for rec in outlet hold; do
    case $rec in outlet) D=$R90/bv_outlet ;; hold) D=$R/bv_hold ;; esac
    for m in s0 s1 e2; do
        case $m in e2) RUN=${D}_s0+${D}_s1 ;; *) RUN=${D}_$m ;; esac
        ROWS="$ROWS ${rec}_${m}_alone=$RUN ${rec}_${m}_auto=$RUN:guards,tolerance_r=$AUTO"
    done
done
python $CE $OUT/heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 \
    "BendVessel, held out (190 degrees outside the training rotations): the outlet recipe without and with the lateral hold (--lateral-hold 2), seeds 0 and 1 (37 epochs) and their ensemble, alone and guarded at auto (0.207 r)" $ROWS
python $CE --sims-kind "validation simulation" $OUT/validation data/bendvessel.h5 \
    bendvessel_009 "BendVessel, validation: the same rows" $ROWS
# How deep the clot lies outside the wall when the models roll out alone
for m in outlet_s0:$R90/bv_outlet_s0 outlet_s1:$R90/bv_outlet_s1 hold_s0:$R/bv_hold_s0 hold_s1:$R/bv_hold_s1; do
    thrombojax rollout --run ${m#*:} --dataset data/bendvessel.h5 --no-guards --checkpoint last \
        --no-gif --quiet --out $R/alone/${m%%:*}
done
python $OUT/outside_depth.py data/bendvessel.h5 outlet_s0=$R/alone/outlet_s0 outlet_s1=$R/alone/outlet_s1 \
    hold_s0=$R/alone/hold_s0 hold_s1=$R/alone/hold_s1 > $OUT/outside_depth.md
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --out $OUT/track.md $OUT/heldout \
    outlet_s0_auto,hold_s0_auto,outlet_s1_auto,hold_s1_auto,outlet_e2_auto,hold_e2_auto,outlet_s0_alone,hold_s0_alone,outlet_s1_alone,hold_s1_alone
# The vessel-following prior alone, no model
python $OUT/prior_drift.py data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 > $OUT/prior_drift.md
# The centring guard (rollout time) on the outlet recipe's seeds and ensemble, at auto (0.0817 r:
# fit_centring on the 16 training simulations, what `thrombojax rollout --centring auto` picks),
# guarded at auto; written to /work/exp/s91/bv_eval_c/{heldout,validation} and copied into centring/
CAUTO=0.08172344416379929
ROWS=""
for m in s0 s1 e2; do
    case $m in e2) RUN=${R90}/bv_outlet_s0+${R90}/bv_outlet_s1 ;; *) RUN=${R90}/bv_outlet_$m ;; esac
    ROWS="$ROWS outlet_${m}_auto=$RUN:guards,tolerance_r=$AUTO outlet_${m}_centre=$RUN:guards,tolerance_r=$AUTO,centring_r=$CAUTO"
done
python $CE $OUT/centring/heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 \
    "BendVessel, held out: the outlet recipe's seeds 0 and 1 and their ensemble, guarded at auto (0.207 r), without and with the centring guard at auto (0.082 r)" $ROWS
python $CE --sims-kind "validation simulation" $OUT/centring/validation data/bendvessel.h5 bendvessel_009 \
    "BendVessel, validation: the same rows" $ROWS
python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --out $OUT/centring/track.md $OUT/centring/heldout \
    outlet_s0_auto,outlet_s0_centre,outlet_s1_auto,outlet_s1_centre,outlet_e2_auto,outlet_e2_centre
