#!/usr/bin/env bash
# Validates the contention-free client costs (issue 16) against each other:
# on each scene, with 1 and 4 clients, one run with the GL stages taking turns
# (--stage-turns) and LP_NUM_THREADS=0 gives, for the same frames, each
# client's stage wall times (isolated) and its stage threads' CPU time; and
# with 1 client, --in-flight 1 (nothing overlaps) and LP_NUM_THREADS=0, the
# measured wall frame time, which on a quiet machine is what both should
# add up to. DMMR_BENCH_REPS rounds (default 3).
# usage: scripts/bench/cost_validation.sh   (writes out/bench/cost-validation/, prints Markdown)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/cost-validation}
reps=${DMMR_BENCH_REPS:-3}
w=${DMMR_BENCH_WIDTH:-1024}
h=${DMMR_BENCH_HEIGHT:-768}
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
scene plants4 replicate --of plant --copies 4 --triangles 400000 --geodes 5000 --seed 1 --frames 40
scene monuments25 replicate --of monument --copies 25 --triangles 120000 --geodes 500 --seed 1 --frames 40
for r in $(seq 1 "$reps"); do
  for s in plants4 monuments25; do
    for run in "turns-c1|1|--stage-turns $out/turns.lock" "turns-c4|4|--stage-turns $out/turns.lock" \
      "serial-c1|1|--in-flight 1"; do
      IFS='|' read -r label n extra <<<"$run"
      # shellcheck disable=SC2086
      LP_NUM_THREADS=0 "${launch[@]}" -np $((n + 1)) -x LP_NUM_THREADS $bin/dmmr-render \
        --scene out/bench/$s.scene --walkthrough out/bench/$s.generated.path \
        --out "$out/$s-$label-r$r" --stats "$out/$s-$label-r$r.csv" --width "$w" --height "$h" \
        --no-progress $extra >/dev/null
      rm -rf "${out:?}/$s-$label-r$r"  # the frames are not needed here
    done
  done
done
python3 scripts/bench/cost_validation_report.py "$out" "$reps"
