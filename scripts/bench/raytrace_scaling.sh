#!/usr/bin/env bash
# Ray-traced scaling (issue 18): plant10m at 1024x1024, DMMR_BENCH_FRAMES
# (default 12) frames, with 1, 2, 4 and 8 clients, tiles dealt statically
# (rows) and dynamically, 128x128 and 64x64 tiles. Every client traces on
# its render stage thread alone (--ray-threads 1), so that the thread's CPU
# time is its whole cost, free of waiting for one of this machine's 2 cores
# (docs/benchmarks.md, "Per-client cost"): a frame's CPU-derived time is the
# server's cull and divide plus the busiest client's render CPU time, and
# efficiency is tau_1 / (S tau_S) over those. Wall times on 2 cores with up
# to 9 ranks say nothing of a cluster and are not reported.
# DMMR_BENCH_REPEAT=1 walks the path twice and reports the second walk only
# (DMMR_BENCH_WARMUP is then the first walk's length): every client has
# built the BVHs of what its tiles showed on the first walk, as the paper's
# workers hold their prebuilt kd-trees, so what is left is tracing.
# usage: scripts/bench/raytrace_scaling.sh   (writes out/bench/raytrace-scaling/, prints Markdown)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/raytrace-scaling}
frames=${DMMR_BENCH_FRAMES:-12}
size=${DMMR_BENCH_SIZE:-1024}
counts=${DMMR_BENCH_CLIENTS:-1 2 4 8}
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
scene plant10m plant --seed 1 --triangles 10000000 --frames 60
head -n "$frames" out/bench/plant10m.generated.path >"$out/path"
if [ -n "${DMMR_BENCH_REPEAT:-}" ]; then  # the same walk again, later in time
  awk 'NR == FNR { last = $1; step = NR > 1 ? $1 - prev : 0; prev = $1; print; next }
       { $1 = $1 + last + step; print }' "$out/path" "$out/path" >"$out/path2"
  mv "$out/path2" "$out/path"
  export DMMR_BENCH_WARMUP=$frames
fi
for n in $counts; do
  for bal in tiles-static tiles-dynamic; do
    for tile in 128 64; do
      label=c$n-$bal-$tile
      "${launch[@]}" -np $((n + 1)) $bin/dmmr-render --scene out/bench/plant10m.scene \
        --walkthrough "$out/path" --out "$out/$label" --stats "$out/$label.csv" \
        --width "$size" --height "$size" --renderer raytrace --ray-threads 1 \
        --balance "$bal" --tile "${tile}x${tile}" --no-progress >/dev/null
    done
  done
done
python3 scripts/bench/raytrace_scaling_report.py "$out" "$counts"
