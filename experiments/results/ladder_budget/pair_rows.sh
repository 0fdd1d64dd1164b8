#!/bin/bash
# Shell functions the BendVessel commands of ./start_speed/, ./start_speed_noise/,
# ./start_span/ and ./span_speedup/ share (sourced by their commands.sh, which set CE, the
# cross_eval.py script, and AUTO, the coherence tolerance in vessel radii).

copy_rows() {  # SRC OUT PREFIXES: SRC's BendVessel row JSONs (held out and validation) of the
               # (space-separated) PREFIXES' seeds and ensemble (s0, s1, e2), each guarded at
               # auto, wallvel, contain and alone, copied into OUT, where cross_eval.py reuses them
    local d p m k
    for d in heldout validation; do
        mkdir -p $2/bendvessel_$d
        for p in $3; do for m in s0 s1 e2; do for k in auto alone wallvel contain; do
            cp $1/bendvessel_$d/${p}_${m}_$k.json $2/bendvessel_$d/
        done; done; done
    done
}

rows() {  # PREFIX RUN0 RUN1: cross_eval.py rows of two seeds and their ensemble (s0, s1, e2),
          # each guarded at AUTO, with the velocity kept through containment (wallvel), with
          # containment only (contain) and alone
    local out="" m run
    for m in s0 s1 e2; do
        case $m in s0) run=$2;; s1) run=$3;; e2) run=$2+$3;; esac
        out="$out $1_${m}_auto=$run:guards,tolerance_r=$AUTO $1_${m}_wallvel=$run:guards,tolerance_r=$AUTO,keep_velocity_wall=1 $1_${m}_contain=$run:guards,coherence=0 $1_${m}_alone=$run"
    done
    echo $out
}

pair_tables() {  # OUT TITLE PREFIXES ROWS...: OUT's held-out (005, 012, 019) and validation
                 # (009) tables of the rows, and the track split of the rows PREFIX_{s0,s1,e2}_
                 # {auto,contain,alone} for each of the (space-separated) PREFIXES
    local out=$1 title=$2 prefixes=$3 labels="" p m k
    shift 3
    python $CE $out/bendvessel_heldout data/bendvessel.h5 bendvessel_005,bendvessel_012,bendvessel_019 "$title, held out" "$@"
    python $CE --sims-kind "validation simulation" $out/bendvessel_validation data/bendvessel.h5 bendvessel_009 "$title, validation" "$@"
    for p in $prefixes; do for m in s0 s1 e2; do for k in auto contain alone; do labels="$labels,${p}_${m}_$k"; done; done; done
    python experiments/results/ladder_budget/bendvessel_speed_noise/track_table.py --out $out/track.md \
        $out/bendvessel_heldout ${labels#,}
}
