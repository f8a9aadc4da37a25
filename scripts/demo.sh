#!/usr/bin/env bash
# Quick start 1: installs what is missing, builds, generates a plant,
# preprocesses it, renders its walkthrough brute force (dmmr-reference) and
# distributed (mpirun, a server and 2 clients), checks that the two agree
# pixel for pixel, and writes a short report.
#
# Environment: DMMR_DEMO_OUT (default out/demo), DMMR_DEMO_TRIANGLES
# (default 1000000), DMMR_DEMO_SIZE (image side, default 1024).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh dmmr-scenegen dmmr-preprocess dmmr-reference dmmr-render dmmr-compare

out=${DMMR_DEMO_OUT:-out/demo}
tris=${DMMR_DEMO_TRIANGLES:-1000000}
size=${DMMR_DEMO_SIZE:-1024}
bin=build/bin
path=walkthroughs/demo-plant.path
mpi=(mpirun --oversubscribe --bind-to none -np 3)
[ "$(id -u)" -eq 0 ] && mpi+=(--allow-run-as-root)

rm -rf "$out"
mkdir -p "$out"
echo "== generating a plant of about $tris triangles"
$bin/dmmr-scenegen plant --seed 1 --triangles "$tris" -o "$out/plant.osgb" \
  --walkthrough "$out/generated.path" --frames 60
echo "== preprocessing"
$bin/dmmr-preprocess "$out/plant.osgb" -o "$out/scene" | tee "$out/preprocess.txt"
echo "== reference render (brute force, one process)"
$bin/dmmr-reference --scene "$out/scene" --walkthrough "$path" --out "$out/reference" \
  --width "$size" --height "$size" --stats "$out/reference.csv"
echo "== distributed render: ${mpi[*]} (server + 2 clients)"
"${mpi[@]}" $bin/dmmr-render --scene "$out/scene" --walkthrough "$path" --out "$out/distributed" \
  --width "$size" --height "$size" --stats "$out/distributed.csv"
echo "== comparing"
identical=0
$bin/dmmr-compare "$out/reference" "$out/distributed" --csv "$out/compare.csv" >"$out/compare.txt" || identical=$?
compare=$(tail -1 "$out/compare.txt")
echo "$compare"

median() {  # median of column $2 of CSV $1 (header skipped)
  awk -F, -v c="$2" 'NR>1 {print $c}' "$1" | sort -g | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2)}'
}
col() { head -1 "$1" | tr ',' '\n' | grep -nx "$2" | cut -d: -f1; }
ref_ms=$(median "$out/reference.csv" "$(col "$out/reference.csv" frame_ms)")
dist_ms=$(median "$out/distributed.csv" "$(col "$out/distributed.csv" frame_ms)")
frames=$(($(wc -l <"$out/reference.csv") - 1))
cat >"$out/report.md" <<REPORT
# dmmr demo report

- Machine: $(nproc) cores, $(uname -m); renderer: Mesa llvmpipe through OSMesa.
- Scene: $(cat "$out/preprocess.txt")
- Walkthrough: $path, $frames frames at ${size}x${size}.
- Reference (brute force, 1 process): median frame time $ref_ms ms.
- Distributed (server + 2 clients on this one machine): median frame time $dist_ms ms.
- Pixel comparison, distributed against reference: $compare

Frames: $out/reference/, $out/distributed/. Per-frame statistics: $out/reference.csv,
$out/distributed.csv. Both renderers share one 2-core machine here, so the
times say little about a cluster; see docs/benchmarks.md.
REPORT
echo "== report: $out/report.md"
cat "$out/report.md"
if [ "$identical" -ne 0 ]; then
  echo "demo: the distributed frames differ from the reference (see $out/compare.txt)" >&2
  exit 1
fi
