#!/usr/bin/env bash
# dmmr-render (1 client, defaults: conservative visibility, pipelined)
# against dmmr-reference on plant10m, alternated A B A B over N pairs so that
# the machine's drift hits both alike; prints each pair's ratio of median
# frame times (frames 1..) and their median. Needs the scene made by
# scripts/bench/visibility.sh.
# usage: scripts/bench/visibility_ab.sh [pairs]   (default 3)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=build/bin
out=out/bench/vis-ab
pairs=${1:-3}
size=${DMMR_BENCH_SIZE:-512}
mpi=(mpirun --oversubscribe --bind-to none -np 2)
[ "$(id -u)" -eq 0 ] && mpi+=(--allow-run-as-root)
scene=out/bench/plant10m.scene
path=walkthroughs/plant10m.path
mkdir -p "$out"
for i in $(seq 1 "$pairs"); do
  rm -rf "$out/ref" "$out/dmmr"
  $bin/dmmr-reference --scene "$scene" --walkthrough "$path" --out "$out/ref" --width "$size" \
    --height "$size" --stats "$out/ref-$i.csv" --no-progress
  "${mpi[@]}" $bin/dmmr-render --scene "$scene" --walkthrough "$path" --out "$out/dmmr" \
    --width "$size" --height "$size" --stats "$out/dmmr-$i.csv" --no-progress
  $bin/dmmr-compare "$out/ref" "$out/dmmr" >/dev/null  # exact, or the script fails
done
python3 - "$out" "$pairs" <<'PY'
import csv, statistics, sys
out, pairs = sys.argv[1], int(sys.argv[2])
def med(path):
    return statistics.median(float(r["frame_ms"]) for r in list(csv.DictReader(open(path)))[1:])
rows = [(med(f"{out}/ref-{i}.csv"), med(f"{out}/dmmr-{i}.csv")) for i in range(1, pairs + 1)]
print("| pair | dmmr-reference median frame ms | dmmr-render median frame ms | reference / dmmr |")
print("|---|---|---|---|")
for i, (r, d) in enumerate(rows, 1):
    print(f"| {i} | {r:.1f} | {d:.1f} | {r / d:.2f}x |")
ratios = [r / d for r, d in rows]
print(f"\nMedian ratio {statistics.median(ratios):.2f}x (min {min(ratios):.2f}x, max {max(ratios):.2f}x) over {pairs} pairs; every dmmr frame identical to the reference's.")
PY
