#!/usr/bin/env bash
# The geometry cache against its budgets: hit rates per level, bytes read
# from disk and frame time for a walkthrough of 8 replicated plants, with
# the RAM and GPU budgets shrunk step by step below the scene's geometry;
# every run's frames compared with the unlimited run's.
# usage: scripts/bench/cache.sh   (writes out/bench/cache/, prints Markdown)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=build/bin
out=out/bench/cache
size=${DMMR_BENCH_SIZE:-512}
clients=${DMMR_BENCH_CLIENTS:-1}
mpi=(mpirun --oversubscribe --bind-to none -np $((clients + 1)))
[ "$(id -u)" -eq 0 ] && mpi+=(--allow-run-as-root)
mkdir -p "$out"

# 8 copies of a 1.25M-triangle plant (as scripts/bench/distributed.sh makes
# it): 10M triangles, one plant's geometry.
[ -f out/bench/plants8.osgb ] || $bin/dmmr-scenegen replicate --of plant --copies 8 \
  --triangles 1250000 --seed 1 -o out/bench/plants8.osgb >/dev/null
[ -d out/bench/plants8.scene ] || $bin/dmmr-preprocess out/bench/plants8.osgb \
  -o out/bench/plants8.scene --no-progress >/dev/null
scene=out/bench/plants8.scene
path=walkthroughs/plants8-fly.path
geometry=$(python3 -c "import json; print(json.load(open('$scene/manifest.json'))['counts']['geometry_bytes'])")

run() {  # label, options...
  local label=$1
  shift
  rm -rf "${out:?}/$label"
  "${mpi[@]}" $bin/dmmr-render --scene "$scene" --walkthrough "$path" --out "$out/$label" \
    --width "$size" --height "$size" --stats "$out/$label.csv" --no-progress "$@"
}

run unlimited
labels=(unlimited)
# RAM budget = geometry / d; GPU budget (per context) = RAM budget / 2.
for d in 2 4 8 16 32; do
  ram=$((geometry / d))
  gpu=$((ram / 2))
  run "ram-1of$d" --ram-budget "$ram" --gpu-budget "$gpu"
  labels+=("ram-1of$d")
done
d=8
run "ram-1of$d-noprefetch" --ram-budget $((geometry / d)) --gpu-budget $((geometry / d / 2)) --no-prefetch
labels+=("ram-1of$d-noprefetch")
# The same scene with meshoptimizer's lossless codecs: the RAM level keeps
# files as they are, so the same budget holds more of it.
[ -d out/bench/plants8-meshopt.scene ] || $bin/dmmr-preprocess out/bench/plants8.osgb \
  -o out/bench/plants8-meshopt.scene --encoding meshopt --no-progress >/dev/null
d=8
scene=out/bench/plants8-meshopt.scene run "ram-1of$d-meshopt" --ram-budget $((geometry / d)) \
  --gpu-budget $((geometry / d / 2))
labels+=("ram-1of$d-meshopt")
for d in 2 8; do
  run "ram-1of$d-lru" --ram-budget $((geometry / d)) --gpu-budget $((geometry / d / 2)) --eviction lru
  labels+=("ram-1of$d-lru")
done
python3 scripts/bench/cache_report.py "$out" "$geometry" "$clients" "${labels[@]}"
