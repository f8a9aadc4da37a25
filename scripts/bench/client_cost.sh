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
# DMMR_BENCH_SCENES and DMMR_BENCH_CONFIGS (space-separated names and labels)
# run a subset, e.g. DMMR_BENCH_SCENES=plant10m DMMR_BENCH_CONFIGS="pyramid-fused".
# DMMR_BENCH_BASE_BIN (a build's bin directory) adds the configuration
# "base": that build's dmmr-render with its defaults, taking turns with the
# others (an A/B of two builds in one run).
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/client-cost}
size=${DMMR_BENCH_SIZE:-512}
reps=${DMMR_BENCH_REPS:-3}
mkdir -p "$out"

# shellcheck source=lib.sh
source scripts/bench/lib.sh
scenes=${DMMR_BENCH_SCENES:-plant10m monument4m skulls25}
models=${DMMR_MODELS:-../shared/models}
for s in $scenes; do
  case $s in
    plant10m) scene plant10m plant --seed 1 --triangles 10000000 --frames 60 ;;
    monument4m) scene monument4m monument --seed 1 --triangles 4000000 --frames 60 ;;
    skulls25) scene skulls25 replicate --input "$models/skull/skull.obj" --copies 25 --frames 60 ;;
    *) echo "client_cost.sh: unknown scene $s" >&2; exit 2 ;;
  esac
done

configs=(  # label|dmmr-render options; pyramid-split is the default
  "queries-split|--visibility queries --stages split"
  "pyramid-split|--visibility pyramid --stages split"
  "pyramid-split-nocost|--visibility pyramid --stages split --cost-model off"
  "pyramid-fused|--visibility pyramid --stages fused"
  "pyramid-fused-nocost|--visibility pyramid --stages fused --cost-model off"
  "pyramid-fused-predict|--visibility pyramid --stages fused --predict on"
  "pyramid-fused-noparts|--visibility pyramid --stages fused --part-boxes off"
  "pyramid-fused-wholedraws|--visibility pyramid --stages fused --part-draws off"
  "auto|--stages auto"
  "off|--visibility off"
)
if [ -n "${DMMR_BENCH_CONFIGS:-}" ]; then
  chosen=()
  for c in "${configs[@]}"; do
    [[ " $DMMR_BENCH_CONFIGS " == *" ${c%%|*} "* ]] && chosen+=("$c")
  done
  configs=("${chosen[@]}")
fi
[ -n "${DMMR_BENCH_BASE_BIN:-}" ] && configs+=("base|")
view=(--width "$size" --height "$size" --no-progress)
for s in $scenes; do
  p=walkthroughs/$s.path
  $bin/dmmr-reference --scene "out/bench/$s.scene" --walkthrough "$p" --out "$out/$s-exact" \
    "${view[@]}" --stats "$out/$s-exact.csv" --exact-visible
  for r in $(seq 1 "$reps"); do
    $bin/dmmr-reference --scene "out/bench/$s.scene" --walkthrough "$p" --out "$out/$s-ref" \
      "${view[@]}" --stats "$out/$s-ref-r$r.csv"
    for c in "${configs[@]}"; do
      label=${c%%|*}
      render=$bin/dmmr-render
      [ "$label" = base ] && render=$DMMR_BENCH_BASE_BIN/dmmr-render
      # shellcheck disable=SC2086
      "${mpi[@]}" "$render" --scene "out/bench/$s.scene" --walkthrough "$p" \
        --out "$out/$s-$label" "${view[@]}" --stats "$out/$s-$label-r$r.csv" ${c#*|}
      diff_frames "$out/$s-ref" "$out/$s-$label" "$out/$s-$label-r$r.cmp.csv"
    done
  done
done
# shellcheck disable=SC2086
python3 scripts/bench/client_cost_report.py "$out" "$reps" $scenes
