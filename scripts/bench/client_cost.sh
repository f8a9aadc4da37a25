#!/usr/bin/env bash
# One client's cost (issue 13): dmmr-render with each visibility method and
# stage mode against dmmr-reference (llvmpipe's default threads), side by
# side in one run: the reference and every configuration take turns, DMMR_BENCH_REPS
# (default 3) times, on plant10m (much hidden), monument4m, and skulls25 (25
# scanned skulls spaced apart, the camera among them: little hidden). One
# reference run with --exact-visible gives the exactly visible set and the
# fill-rate floor (drawing that set alone). Every frame is compared with the
# reference's.
# usage: scripts/bench/client_cost.sh   (writes out/bench/client-cost/, prints Markdown)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/client-cost}
size=${DMMR_BENCH_SIZE:-512}
reps=${DMMR_BENCH_REPS:-3}
mkdir -p "$out"

# shellcheck source=lib.sh
source scripts/bench/lib.sh
scene plant10m plant --seed 1 --triangles 10000000 --frames 60
scene monument4m monument --seed 1 --triangles 4000000 --frames 60
models=${DMMR_MODELS:-../shared/models}
scene skulls25 replicate --input "$models/skull/skull.obj" --copies 25 --frames 60

configs=(  # label|dmmr-render options; pyramid-split is the default
  "queries-split|--visibility queries --stages split"
  "pyramid-split|--visibility pyramid --stages split"
  "pyramid-split-nocost|--visibility pyramid --stages split --cost-model off"
  "pyramid-fused|--visibility pyramid --stages fused"
  "pyramid-fused-nocost|--visibility pyramid --stages fused --cost-model off"
  "auto|--stages auto"
  "off|--visibility off"
)
view=(--width "$size" --height "$size" --no-progress)
for s in plant10m monument4m skulls25; do
  p=walkthroughs/$s.path
  $bin/dmmr-reference --scene "out/bench/$s.scene" --walkthrough "$p" --out "$out/$s-exact" \
    "${view[@]}" --stats "$out/$s-exact.csv" --exact-visible
  for r in $(seq 1 "$reps"); do
    $bin/dmmr-reference --scene "out/bench/$s.scene" --walkthrough "$p" --out "$out/$s-ref" \
      "${view[@]}" --stats "$out/$s-ref-r$r.csv"
    for c in "${configs[@]}"; do
      label=${c%%|*}
      # shellcheck disable=SC2086
      "${mpi[@]}" $bin/dmmr-render --scene "out/bench/$s.scene" --walkthrough "$p" \
        --out "$out/$s-$label" "${view[@]}" --stats "$out/$s-$label-r$r.csv" ${c#*|}
      $bin/dmmr-compare "$out/$s-ref" "$out/$s-$label" --csv "$out/$s-$label-r$r.cmp.csv" \
        --min-psnr 0 --max-diff-pixels 999999999 >/dev/null
    done
  done
done
python3 scripts/bench/client_cost_report.py "$out" "$reps" plant10m monument4m skulls25
