#!/usr/bin/env bash
# Fewer rays for speed (issue 18): ray-traced dmmr, 1 client, with
# --ray-stride 1 (every pixel, the exact ray-traced frame), 2, 3 and 4 (one
# primary ray per NxN pixels, the rest interpolated bilinearly), side by side
# in one run, on plant10m and plants100m at 1024x1024, DMMR_BENCH_FRAMES
# frames (default 12) of each generated path. Each strided frame is compared
# with the stride-1 frame (the stride's own error) and with dmmr-reference's
# raster frame (the whole error). Frame time: the median of frame_ms from
# frame 4 on, and of the client's render_ms (the tracing).
# usage: scripts/bench/raytrace_stride.sh   (writes out/bench/raytrace-stride/, prints Markdown)
# DMMR_BENCH_SCENES, DMMR_BENCH_SIZE and DMMR_BENCH_STRIDES pick subsets.
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/raytrace-stride}
frames=${DMMR_BENCH_FRAMES:-12}
size=${DMMR_BENCH_SIZE:-1024}
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
scenes=${DMMR_BENCH_SCENES:-plant10m plants100m}
strides=${DMMR_BENCH_STRIDES:-1 2 3 4}
for s in $scenes; do
  case $s in
    plant10m) scene plant10m plant --seed 1 --triangles 10000000 --frames 60 ;;
    plants100m) scene plants100m replicate --of plant --copies 10 --triangles 10000000 --seed 1 \
      --frames 60 ;;
    *) echo "raytrace_stride.sh: unknown scene $s" >&2; exit 2 ;;
  esac
  head -n "$frames" "out/bench/$s.generated.path" >"$out/$s.path"
  view=(--width "$size" --height "$size" --no-progress)
  $bin/dmmr-reference --scene "out/bench/$s.scene" --walkthrough "$out/$s.path" \
    --out "$out/$s-ref" "${view[@]}"
  for n in $strides; do
    "${mpi[@]}" $bin/dmmr-render --scene "out/bench/$s.scene" --walkthrough "$out/$s.path" \
      --out "$out/$s-s$n" "${view[@]}" --stats "$out/$s-s$n.csv" --renderer raytrace \
      --ray-stride "$n"
    for against in ref s1; do
      $bin/dmmr-compare "$out/$s-$against" "$out/$s-s$n" --csv "$out/$s-s$n-vs-$against.cmp.csv" \
        --min-psnr 0 --max-diff-pixels 999999999 >/dev/null
    done
  done
done
python3 scripts/bench/raytrace_stride_report.py "$out" "$scenes" "$strides"
