#!/usr/bin/env bash
# Ray-traced against rasterised dmmr, 1 client (issue 18), side by side in one
# run on this machine: plant1m, plant10m and plants100m (10 instanced copies
# of a 10M-triangle plant: 100M triangles, 10M unique), at 512x512 and
# 1024x1024, each walked DMMR_BENCH_FRAMES frames (default 24) of its
# generated path. Configurations: raster (the default visibility, pyramid
# with fused stages), raytrace (primary rays), raytrace --shadows. Every
# frame is compared with dmmr-reference's (the raster reference): the ray
# tracer's sampling differs at edges, so its PSNR and differing pixels are
# the error. Frame time: the median of the stats CSV's frame_ms from frame 4
# on (the first frames build BVHs and upload meshes).
# usage: scripts/bench/raytrace.sh   (writes out/bench/raytrace/, prints Markdown)
# DMMR_BENCH_SCENES and DMMR_BENCH_SIZES pick subsets.
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/raytrace}
frames=${DMMR_BENCH_FRAMES:-24}
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
scenes=${DMMR_BENCH_SCENES:-plant1m plant10m plants100m}
sizes=${DMMR_BENCH_SIZES:-512 1024}
for s in $scenes; do
  case $s in
    plant1m) scene plant1m plant --seed 1 --triangles 1000000 --frames 60 ;;
    plant10m) scene plant10m plant --seed 1 --triangles 10000000 --frames 60 ;;
    plants100m) scene plants100m replicate --of plant --copies 10 --triangles 10000000 --seed 1 \
      --frames 60 ;;
    *) echo "raytrace.sh: unknown scene $s" >&2; exit 2 ;;
  esac
  head -n "$frames" "out/bench/$s.generated.path" >"$out/$s.path"
done

configs=(  # label|dmmr-render options
  "raster|"
  "raytrace|--renderer raytrace"
  "raytrace-shadows|--renderer raytrace --shadows"
)
for size in $sizes; do
  for s in $scenes; do
    view=(--width "$size" --height "$size" --no-progress)
    $bin/dmmr-reference --scene "out/bench/$s.scene" --walkthrough "$out/$s.path" \
      --out "$out/$s-$size-ref" "${view[@]}" --stats "$out/$s-$size-ref.csv"
    for c in "${configs[@]}"; do
      label=${c%%|*}
      # shellcheck disable=SC2086
      "${mpi[@]}" $bin/dmmr-render --scene "out/bench/$s.scene" --walkthrough "$out/$s.path" \
        --out "$out/$s-$size-$label" "${view[@]}" --stats "$out/$s-$size-$label.csv" ${c#*|}
      $bin/dmmr-compare "$out/$s-$size-ref" "$out/$s-$size-$label" \
        --csv "$out/$s-$size-$label.cmp.csv" --min-psnr 0 --max-diff-pixels 999999999 >/dev/null
    done
  done
done
python3 scripts/bench/raytrace_report.py "$out" "$sizes" "$scenes" "${configs[@]}"
