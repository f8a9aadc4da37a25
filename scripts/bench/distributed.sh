#!/usr/bin/env bash
# Server division time against objects in the frustum, load balance and
# sub-frame bytes on 8 instanced plants (10M triangles, 160,000 objects).
# usage: scripts/bench/distributed.sh   (writes out/bench/)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=build/bin
out=out/bench
size=${DMMR_BENCH_SIZE:-1024}
mpi=(mpirun --oversubscribe --bind-to none)
[ "$(id -u)" -eq 0 ] && mpi+=(--allow-run-as-root)
mkdir -p "$out"
[ -f "$out/plants8.osgb" ] || $bin/dmmr-scenegen replicate --of plant --copies 8 --triangles 1250000 \
  --seed 1 -o "$out/plants8.osgb" --walkthrough "$out/plants8.path" --frames 40 >/dev/null
[ -d "$out/plants8.scene" ] || $bin/dmmr-preprocess "$out/plants8.osgb" -o "$out/plants8.scene" --no-progress >/dev/null
[ -f "$out/plants5.osgb" ] || $bin/dmmr-scenegen replicate --of plant --copies 5 --triangles 1250000 \
  --seed 1 -o "$out/plants5.osgb" --path orbit --frames 20 >/dev/null
[ -d "$out/plants5.scene" ] || $bin/dmmr-preprocess "$out/plants5.osgb" -o "$out/plants5.scene" --no-progress >/dev/null
scene=$out/plants8.scene

echo "### Division time against objects in the frustum (dmmr-plan, ${size}x${size}, median of 5 plans per frame)"
echo
$bin/dmmr-plan --scene "$scene" --walkthrough walkthroughs/plants8-fly.path --clients 2 4 8 \
  --width "$size" --height "$size" --csv "$out/plan-fly.csv"
$bin/dmmr-plan --scene "$scene" --walkthrough walkthroughs/plants8-orbit.path --clients 2 4 8 \
  --width "$size" --height "$size" --csv "$out/plan-orbit.csv"
$bin/dmmr-plan --scene "$out/plants5.scene" --walkthrough walkthroughs/plants5-orbit.path --clients 2 4 8 \
  --width "$size" --height "$size" --csv "$out/plan-orbit5.csv"
python3 - "$out/plan-fly.csv" "$out/plan-orbit.csv" "$out/plan-orbit5.csv" <<'PY'
import csv, statistics, sys
rows = [r for p in sys.argv[1:] for r in csv.DictReader(open(p))]
buckets = {}
for r in rows:
    o = int(r["objects_in_frustum"])
    b = next(k for k in (160000, 120000, 100000, 50000, 20000, 10000, 5000, 1000, 0) if o >= k)
    buckets.setdefault((b, int(r["clients"])), []).append(r)
print("| objects in frustum | clients | frames | cull ms | project ms | divide ms (incl. project) | max region / mean |")
print("|---|---|---|---|---|---|---|")
for (b, c) in sorted(buckets):
    v = buckets[(b, c)]
    med = lambda k: statistics.median(float(r[k]) for r in v)
    bal = statistics.median(float(r["max_region_triangles"]) / max(float(r["mean_region_triangles"]), 1) for r in v)
    print(f"| {b:,}+ | {c} | {len(v)} | {med('cull_ms'):.2f} | {med('project_ms'):.2f} | {med('divide_ms'):.2f} | {bal:.3f} |")
PY
echo
echo "### Rendering with 2 and 4 clients (mpirun, one 2-core machine, ${size}x${size})"
echo
runs=()
for n in 2 4; do
  "${mpi[@]}" -np $((n + 1)) $bin/dmmr-render --scene "$scene" --walkthrough walkthroughs/plants8-fly.path \
    --out "$out/render$n" --width "$size" --height "$size" --stats "$out/render$n.csv" --no-progress
  runs+=("$out/render$n.csv")
done
python3 scripts/summarize_stats.py "${runs[@]}" | sed -n '1,4p'
