#!/usr/bin/env bash
# How well the division's inputs predict each client's time (issue 16):
# dmmr-render --division-log on the scaling suite's medium scenes (plants4,
# plants8, monuments16 at 1024x768, 40 frames) with each client count in
# DMMR_BENCH_CLIENTS (default "4 16"), every run LP_NUM_THREADS=0 (a client's
# cost is its stage threads' CPU time, the scaling suite's method), then
# scripts/bench/division_log_report.py over the logs: R^2 of client time
# against the client's own counts (hindsight) and against the server's forecast
# at plan time, and the imbalance each would leave. DMMR_BENCH_OPTIONS: more
# dmmr-render options (default --catch-up off: catching up makes the planned
# shares unequal on purpose, and this measures the forecast).
# usage: scripts/bench/division_log.sh   (writes out/bench/division-log/, prints Markdown)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/division-log}
counts=${DMMR_BENCH_CLIENTS:-4 16}
scenes=${DMMR_BENCH_SCENES:-plants4 plants8 monuments16}
options=${DMMR_BENCH_OPTIONS:---catch-up off}
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
logs=()
for s in $scenes; do
  case $s in
    plants4 | plants8)
      scene "$s" replicate --of plant --copies "${s#plants}" --triangles 400000 --geodes 5000 \
        --seed 1 --frames 40 ;;
    monuments16)
      scene monuments16 replicate --of monument --copies 16 --triangles 120000 --geodes 500 \
        --seed 1 --frames 40 ;;
    *) echo "division_log.sh: unknown scene $s" >&2 && exit 1 ;;
  esac
  for n in $counts; do
    run=$out/$s-c$n
    rm -rf "$run"
    LP_NUM_THREADS=0 "${launch[@]}" -np $((n + 1)) -x LP_NUM_THREADS $bin/dmmr-render \
      --scene "out/bench/$s.scene" --walkthrough "out/bench/$s.generated.path" --out "$run" \
      --stats "$run.csv" --division-log "$run.division.csv" --width 1024 --height 768 \
      --no-progress $options >/dev/null 2>"$run.log"
    logs+=("$s-c$n=$run.division.csv")
  done
done
/usr/bin/python3 scripts/bench/division_log_report.py "${logs[@]}" | tee "$out/report.md"
