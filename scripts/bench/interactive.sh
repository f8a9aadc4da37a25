#!/usr/bin/env bash
# Interactive mode (issue 17): dmmr-pose-replay streams a walkthrough at 60 Hz
# as live poses to `dmmr-render --serve` (a head-mounted display's rate), on
# the medium scale's plants4 and monuments25 (512x384), with 1 and 2 clients
# (and 2 clients with 2 frames in flight).
# Per configuration:
#   - a walkthrough run of the same path (dmmr-render, default pipeline, 3
#     frames in flight): its frame time, what the latency is held against;
#   - DMMR_BENCH_SECONDS (default 60) of poses with JPEG frames (quality 80):
#     poses served against sent, pose-to-frame latency (median, p95, first
#     and second half of the run: growth would mean queueing);
#   - DMMR_BENCH_PNG_SECONDS (default 15) of poses with every frame PNG, for
#     bytes and encode time against JPEG.
# Every process on this one 2-core machine: the server, the clients, the
# replay. Wall-clock latency is what a person would feel here.
# usage: scripts/bench/interactive.sh   (writes out/bench/interactive/, prints Markdown)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/interactive}
seconds=${DMMR_BENCH_SECONDS:-60}
png_seconds=${DMMR_BENCH_PNG_SECONDS:-15}
w=${DMMR_BENCH_WIDTH:-512}
h=${DMMR_BENCH_HEIGHT:-384}
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
scene plants4 replicate --of plant --copies 4 --triangles 400000 --geodes 5000 --seed 1 --frames 80
scene monuments25 replicate --of monument --copies 25 --triangles 120000 --geodes 500 --seed 1 \
  --frames 80

server_pid=""
stop_server() {
  if [ -n "$server_pid" ]; then
    kill -TERM "$server_pid" 2>/dev/null || true
    wait "$server_job" 2>/dev/null || true
    server_pid=""
  fi
}
trap stop_server EXIT

# name|clients|frames in flight while serving (1, the default, or 2: a
# pipeline across server and clients, which a cluster has the cores for)
configs=("plants4|1|1" "plants4|2|1" "plants4|2|2" "monuments25|1|1" "monuments25|2|1"
  "monuments25|2|2")
for c in "${configs[@]}"; do
  IFS='|' read -r name n inflight <<<"$c"
  sc=out/bench/$name.scene
  path=out/bench/$name.generated.path
  tag=$name-c$n-f$inflight
  if [ ! -f "$out/$name-c$n-walk.csv" ]; then
    "${launch[@]}" -np $((n + 1)) $bin/dmmr-render --scene $sc --walkthrough $path \
      --out "$out/$name-c$n-walk" --stats "$out/$name-c$n-walk.csv" --width "$w" --height "$h" \
      --no-progress >/dev/null
  fi
  {
    "${launch[@]}" -np $((n + 1)) $bin/dmmr-render --scene $sc --walkthrough $path \
      --serve 127.0.0.1:0 --stats "$out/$tag-serve.csv" --width "$w" --height "$h" \
      --in-flight "$inflight" 2>"$out/$tag-serve.log" &
    server_job=$!
    url=""
    for _ in $(seq 1 600); do
      url=$(grep -o 'http://[^ ]*' "$out/$tag-serve.log" || true)
      [ -n "$url" ] && break
      sleep 0.1
    done
    [ -n "$url" ] || { echo "interactive.sh: no URL from the server" >&2; cat "$out/$tag-serve.log" >&2; exit 1; }
    server_pid=$(sed -n 's/.*server pid \([0-9]*\).*/\1/p' "$out/$tag-serve.log")
    $bin/dmmr-pose-replay --url "$url" --walkthrough $path --rate 60 --duration "$seconds" \
      --quality 80 --csv "$out/$tag-jpeg.csv" --summary "$out/$tag-jpeg.json" >/dev/null
    $bin/dmmr-pose-replay --url "$url" --walkthrough $path --rate 60 --duration "$png_seconds" \
      --quality 0 --csv "$out/$tag-png.csv" --summary "$out/$tag-png.json" >/dev/null
    stop_server
  }
done
python3 scripts/bench/interactive_report.py "$out" "${configs[@]}"
