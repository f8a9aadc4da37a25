#!/usr/bin/env bash
# Fitted division weights and heterogeneous clients (issue 16): 4 clients on
# a 4-plant scene, with and without one client slowed 2x (DMMR_SLOW_CLIENT:
# its render stage spins as long again as it worked), division weights
# `visible` (triangles drawn lately) against `fitted` (a cost model and each
# client's speed fitted to the clients' reports, the default) without and with
# catching up (--catch-up, the default), and 1 client for the ideal. Every run with LP_NUM_THREADS=0, so that the stage
# threads' CPU time is each client's whole cost (the figures below), free of
# waiting for one of this machine's cores. DMMR_BENCH_REPS rounds (default
# 3), the configurations alternating in each. Every frame is compared with
# dmmr-reference's.
# usage: scripts/bench/hetero.sh   (writes out/bench/hetero/, prints Markdown)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/hetero}
reps=${DMMR_BENCH_REPS:-3}
w=${DMMR_BENCH_WIDTH:-1024}
h=${DMMR_BENCH_HEIGHT:-768}
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
# DMMR_BENCH_SCENE and DMMR_BENCH_PATH: another preprocessed scene and its
# walkthrough (for example the scaling suite's large plants6) instead.
if [ -n "${DMMR_BENCH_SCENE:-}" ]; then
  sc=$DMMR_BENCH_SCENE
  path=${DMMR_BENCH_PATH:?DMMR_BENCH_PATH: the walkthrough of DMMR_BENCH_SCENE}
else
  scene plants4 replicate --of plant --copies 4 --triangles 400000 --geodes 5000 --seed 1 --frames 40
  sc=out/bench/plants4.scene
  path=out/bench/plants4.generated.path
fi

if [ ! -f "$out/ref/frame_000039.png" ]; then
  rm -rf "$out/ref"
  $bin/dmmr-reference --scene $sc --walkthrough $path --out "$out/ref" --width "$w" --height "$h" \
    --no-progress >/dev/null
fi

configs=(  # label|clients|slowed client (0: none)|dmmr-render options
  "c1|1|0|--weights visible"
  "c4-visible|4|0|--weights visible"
  "c4-fitted|4|0|--weights fitted --catch-up off"
  "c4-catch-up|4|0|--weights fitted --catch-up on"
  "c4-slow-visible|4|2|--weights visible"
  "c4-slow-fitted|4|2|--weights fitted --catch-up off"
  "c4-slow-catch-up|4|2|--weights fitted --catch-up on"
)
for r in $(seq 1 "$reps"); do
  for c in "${configs[@]}"; do
    IFS='|' read -r label n slow opts <<<"$c"
    rm -rf "$out/$label-r$r"
    LP_NUM_THREADS=0 DMMR_SLOW_CLIENT="$slow:2" "${launch[@]}" -np $((n + 1)) \
      -x LP_NUM_THREADS -x DMMR_SLOW_CLIENT $bin/dmmr-render --scene $sc --walkthrough $path \
      --out "$out/$label-r$r" --stats "$out/$label-r$r.csv" --width "$w" --height "$h" \
      $opts --no-progress >/dev/null
    diff_frames "$out/ref" "$out/$label-r$r" "$out/$label-r$r.cmp.csv"
  done
done
python3 scripts/bench/hetero_report.py "$out" "$reps" "${configs[@]}"
