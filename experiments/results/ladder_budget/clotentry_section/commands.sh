# The vessel's width at the clot as an input (--section-features 1) on one rung's ClotEntry
# ensembles (the room recipe, 2-epoch seeds); AMD EPYC 2-core (cpu family 25, model 17),
# jax 0.10.2, tcmalloc, 2026-12-05. data/clotentry.h5 is the file of ../clotentry_pace/
# (`thrombojax generate clotentry` on this machine, dataset fingerprint 4b80c428... in every
# training/seed_*/config.json), so seeds 10-16 here differ from ../clotentry_pace/'s only by
# the new input. Each JSON keeps the load it was measured at.
cd /work/main
export LD_PRELOAD=/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4
export JAX_COMPILATION_CACHE_DIR=/work/.jaxcache
D=experiments/results/ladder_budget/clotentry_section
# 0. the data alone: the width, the clearance and the squeeze along every true track
#    (width_track.json)
python $D/width_track.py $D/width_track.json data/clotentry.h5 \
  clotentry_000,clotentry_001,clotentry_002,clotentry_003,clotentry_004,clotentry_005,clotentry_006,clotentry_007,clotentry_008,clotentry_009
# the room recipe's 2-epoch member config (../clotentry_budget_members/training/seed_13/)
CFG=experiments/results/ladder_budget/clotentry_budget_members/training/seed_13/config.json
# 1. three seeds at once (00:50-01:11, 20 min 25-32 s each, beside the new tests for their
#    first 8 minutes), then four (01:18-01:45, 26 min 20-24 s each, alone); each wave is
#    within one rung's 30 minutes
for s in 10 11 12; do
  thrombojax train --config $CFG --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 \
    --section-features 1 --seed $s --out /work/exp/sec/s$s --quiet &
done; wait
CE=experiments/results/ladder_budget/bendvessel_shapes/cross_eval.py
M=/work/exp/sec; S3=$M/s10+$M/s11+$M/s12
T="ClotEntry, held out (2-epoch seeds of the room recipe with the section width as one ensemble)"
python $CE --nodes 2048 $M/heldout3 data/clotentry.h5 clotentry_008,clotentry_009 "$T" s3_guards=$S3:guards
for s in 13 14 15 16; do
  thrombojax train --config $CFG --dataset data/clotentry.h5 --epochs 2 --warmup-epochs 0.67 \
    --section-features 1 --seed $s --out /work/exp/sec/s$s --quiet &
done; wait
S4=$M/s13+$M/s14+$M/s15+$M/s16; S7=$S3+$S4
python $CE --nodes 2048 $M/heldout47 data/clotentry.h5 clotentry_008,clotentry_009 "$T" \
  s4_guards=$S4:guards s7_guards=$S7:guards
# 2. one table beside the same seeds without the input (../clotentry_pace/heldout/e*_guards.json
#    copied in as room_e*_guards.json): every row's JSON is reused, nothing rolled out again
H=$D/heldout; P=/work/exp/pc
cp $M/heldout3/s3_guards.json $M/heldout47/s4_guards.json $M/heldout47/s7_guards.json $H/
for e in e3 e4 e7; do cp experiments/results/ladder_budget/clotentry_pace/heldout/${e}_guards.json $H/room_${e}_guards.json; done
python $CE --nodes 2048 $H data/clotentry.h5 clotentry_008,clotentry_009 \
  "ClotEntry, held out: one rung's 2-epoch ensembles of the room recipe, with the section width (s*) and without it (room_*, ../clotentry_pace/)" \
  room_e3_guards=$P/s10+$P/s11+$P/s12:guards s3_guards=$S3:guards \
  room_e4_guards=$P/s13+$P/s14+$P/s15+$P/s16:guards s4_guards=$S4:guards \
  room_e7_guards=$P/s10+$P/s11+$P/s12+$P/s13+$P/s14+$P/s15+$P/s16:guards s7_guards=$S7:guards
# the copies are those files byte for byte: removed again, the table and ladder.json keep the rows
rm $H/room_e3_guards.json $H/room_e4_guards.json $H/room_e7_guards.json
