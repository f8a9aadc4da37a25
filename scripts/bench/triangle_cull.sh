#!/usr/bin/env bash
# Exact triangle culling on and off, side by side (--triangle-cull; issues 15
# and 16): skullmesh4 (issue 15's four 2.5M-triangle skull meshes in 4096-
# triangle clusters, 512x512, walkthroughs/skullmesh4.path) and the medium
# scenes plants4 and monuments16 (1024x768, 40 frames), where triangles are
# larger and the test should stay out of the way. Per round: dmmr-reference
# (brute force), then dmmr-render with 1 client (llvmpipe's default threads,
# as the reference) off and on, and with 4 clients (LP_NUM_THREADS=1 per
# rank) off and on, the order of off and on swapped every round. Every frame
# of every run is compared with the reference's.
# Environment: DMMR_BENCH_REPS (rounds, default 3), DMMR_BENCH_SCENES
# (default "skullmesh4 plants4 monuments16"), DMMR_BENCH_OUT (default
# out/bench/triangle-cull). DMMR_BENCH_BASE=DIR makes it an A/B of two
# builds: the "off" runs become DIR/dmmr-render's (another build's bin
# directory) with its default culling, labelled "base" in the table.
# usage: scripts/bench/triangle_cull.sh   (prints a Markdown table)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/triangle-cull}
reps=${DMMR_BENCH_REPS:-3}
base=${DMMR_BENCH_BASE:-}
scenes=${DMMR_BENCH_SCENES:-skullmesh4 plants4 monuments16}
models=${DMMR_MODELS:-../shared/models}
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
scene_of() {  # sets sc, path, w, h
  case $1 in
    skullmesh4)
      [ -f out/bench/skullmesh4.osgb ] || "$bin"/dmmr-scenegen replicate \
        --input "$models/skull/skull.obj" --subdivide 5 --copies 4 --path around --frames 48 \
        -o out/bench/skullmesh4.osgb --walkthrough out/bench/skullmesh4.generated.path >/dev/null
      [ -d out/bench/skullmesh4.scene ] || "$bin"/dmmr-preprocess out/bench/skullmesh4.osgb \
        -o out/bench/skullmesh4.scene --no-progress >/dev/null
      sc=out/bench/skullmesh4.scene path=walkthroughs/skullmesh4.path w=512 h=512
      ;;
    plants4)
      scene plants4 replicate --of plant --copies 4 --triangles 400000 --geodes 5000 --seed 1 \
        --frames 40
      sc=out/bench/plants4.scene path=out/bench/plants4.generated.path w=1024 h=768
      ;;
    monuments16)
      scene monuments16 replicate --of monument --copies 16 --triangles 120000 --geodes 500 \
        --seed 1 --frames 40
      sc=out/bench/monuments16.scene path=out/bench/monuments16.generated.path w=1024 h=768
      ;;
    *) echo "triangle_cull.sh: unknown scene $1" >&2 && exit 1 ;;
  esac
}
retry() { "$@" || "$@"; }
render_of() {  # mode: sets cmd, the dmmr-render command line for it (an array: paths may hold spaces)
  if [ "$1" = off ] && [ -n "$base" ]; then
    cmd=("$base/dmmr-render")
  else
    cmd=("$bin/dmmr-render" --triangle-cull "$1")
  fi
}
for r in $(seq 1 "$reps"); do
  order="off on"
  [ $((r % 2)) -eq 0 ] && order="on off"
  for s in $scenes; do
    scene_of "$s"
    view=(--scene "$sc" --walkthrough "$path" --width "$w" --height "$h" --no-progress)
    "$bin"/dmmr-reference "${view[@]}" --out "$out/$s-ref" --stats "$out/$s-ref-r$r.csv"
    for m in $order; do
      render_of "$m"
      retry "${mpi[@]}" "${cmd[@]}" "${view[@]}" --out "$out/$s-1-$m" \
        --stats "$out/$s-1-$m-r$r.csv" >/dev/null 2>&1
      diff_frames "$out/$s-ref" "$out/$s-1-$m" "$out/$s-1-$m-r$r.cmp.csv"
    done
    for m in $order; do
      render_of "$m"
      LP_NUM_THREADS=1 retry "${launch[@]}" -np 5 -x LP_NUM_THREADS "${cmd[@]}" "${view[@]}" \
        --out "$out/$s-4-$m" --stats "$out/$s-4-$m-r$r.csv" >/dev/null 2>&1
      diff_frames "$out/$s-ref" "$out/$s-4-$m" "$out/$s-4-$m-r$r.cmp.csv"
    done
    uptime >>"$out/load.txt"
  done
done
DMMR_BENCH_OFF_LABEL=${base:+base} python3 scripts/bench/triangle_cull_report.py "$out" "$reps" \
  $scenes
