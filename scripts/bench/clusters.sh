#!/usr/bin/env bash
# Big meshes split into clusters (issue 15): four copies of the scanned skull
# subdivided into one 2.5M-triangle mesh (10M triangles in all), the
# `around` walkthrough close to them, preprocessed with each cluster size
# (0: meshes whole). Per size and run: dmmr-reference, dmmr-render with 1
# client (llvmpipe's default threads, as the reference), and with 4 clients
# (LP_NUM_THREADS=1 per rank, so the per-client times are each one
# thread's work). The sizes and the reference take turns, DMMR_BENCH_REPS
# (default 3) times. Every frame is compared with one reference run of the
# clusters of DMMR_BENCH_EXACT (identical to the whole scene's: the report shows it).
# usage: scripts/bench/clusters.sh   (writes out/bench/clusters/, prints Markdown)
# DMMR_BENCH_CLUSTERS (default "0 4096 8192 16384") and DMMR_BENCH_FRAMES
# (default: every frame of walkthroughs/skullmesh4.path) choose a subset;
# DMMR_BENCH_EXACT (default 4096) the cluster size of the exactly visible set.
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/clusters}
size=${DMMR_BENCH_SIZE:-512}
reps=${DMMR_BENCH_REPS:-3}
sizes=${DMMR_BENCH_CLUSTERS:-0 4096 8192 16384}
models=${DMMR_MODELS:-../shared/models}
mkdir -p "$out" out/bench

# shellcheck source=lib.sh
source scripts/bench/lib.sh
[ -f out/bench/skullmesh4.osgb ] || $bin/dmmr-scenegen replicate \
  --input "$models/skull/skull.obj" --subdivide 5 --copies 4 --path around --frames 48 \
  -o out/bench/skullmesh4.osgb --walkthrough out/bench/skullmesh4.generated.path >/dev/null
path=walkthroughs/skullmesh4.path
if [ -n "${DMMR_BENCH_FRAMES:-}" ]; then
  head -n "$DMMR_BENCH_FRAMES" "$path" >"$out/path"
  path=$out/path
fi
for c in $sizes; do
  [ -d "out/bench/skullmesh4-c$c.scene" ] || $bin/dmmr-preprocess out/bench/skullmesh4.osgb \
    -o "out/bench/skullmesh4-c$c.scene" --cluster-triangles "$c" --no-progress >/dev/null
done
mpi4=(mpirun --oversubscribe --bind-to none -np 5 -x LP_NUM_THREADS)
[ "$(id -u)" -eq 0 ] && mpi4+=(--allow-run-as-root)
view=(--width "$size" --height "$size" --no-progress)
# The exactly visible set at the default cluster size (what culling could
# leave at best) and its draw time alone, the floor.
exact=${DMMR_BENCH_EXACT:-4096}
[ -d "out/bench/skullmesh4-c$exact.scene" ] || $bin/dmmr-preprocess out/bench/skullmesh4.osgb \
  -o "out/bench/skullmesh4-c$exact.scene" --cluster-triangles "$exact" --no-progress >/dev/null
[ -f "$out/truth.csv" ] || $bin/dmmr-reference --scene "out/bench/skullmesh4-c$exact.scene" \
  --walkthrough "$path" --out "$out/truth" "${view[@]}" --stats "$out/truth.csv" --exact-visible
# A run that fails is tried once more (another user's network tests on this
# machine have taken an MPI link down under a run); rounds already complete
# in $out are kept, so an interrupted benchmark resumes.
retry() { "$@" || "$@"; }
for r in $(seq 1 "$reps"); do
  for c in $sizes; do
    [ -f "$out/c$c-4-r$r.cmp.csv" ] && continue
    s=out/bench/skullmesh4-c$c.scene
    $bin/dmmr-reference --scene "$s" --walkthrough "$path" --out "$out/c$c-ref" "${view[@]}" \
      --stats "$out/c$c-ref-r$r.csv"
    retry "${mpi[@]}" $bin/dmmr-render --scene "$s" --walkthrough "$path" --out "$out/c$c-1" \
      "${view[@]}" --stats "$out/c$c-1-r$r.csv"
    LP_NUM_THREADS=1 retry "${mpi4[@]}" $bin/dmmr-render --scene "$s" --walkthrough "$path" \
      --out "$out/c$c-4" "${view[@]}" --stats "$out/c$c-4-r$r.csv"
    for k in ref 1 4; do
      diff_frames "$out/truth" "$out/c$c-$k" "$out/c$c-$k-r$r.cmp.csv"
    done
    uptime >>"$out/load.txt"
  done
done
# shellcheck disable=SC2086
python3 scripts/bench/clusters_report.py "$out" "$reps" $sizes
