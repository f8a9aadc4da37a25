#!/usr/bin/env bash
# Preprocessing throughput and peak memory on generated plants.
# usage: scripts/bench/preprocess.sh [RUNS]   (default 5; writes out/bench/)
# Prints a Markdown table: median wall time over RUNS, triangles/s, peak RSS,
# and peak RSS over the scene's geometry size.
set -euo pipefail
cd "$(dirname "$0")/../.."
runs=${1:-5}
bin=build/bin
out=out/bench
mkdir -p "$out"
[ -f "$out/plant10m.osgb" ] || $bin/dmmr-scenegen plant --seed 1 --triangles 10000000 -o "$out/plant10m.osgb" --frames 60 >/dev/null
[ -f "$out/plants8.osgb" ] || $bin/dmmr-scenegen replicate --of plant --copies 8 --triangles 1250000 --seed 1 -o "$out/plants8.osgb" --frames 40 >/dev/null

echo "| input | triangles (instanced) | objects | geometry MB | wall s (median of $runs) | M triangles/s | peak RSS MB | RSS / geometry |"
echo "|---|---|---|---|---|---|---|---|"
for model in plant10m plants8; do
  walls=() rss=()
  # Each run writes a fresh directory: on this machine's file system, creating
  # 20,000 files right after deleting as many is several times slower, which
  # would measure the file system's cleanup rather than the preprocessor.
  rm -rf "$out/$model".run*
  for i in $(seq "$runs"); do
    /usr/bin/time -f "%e %M" -o "$out/time.txt" $bin/dmmr-preprocess "$out/$model.osgb" -o "$out/$model.run$i" --no-progress >/dev/null
    read -r w m <"$out/time.txt"
    walls+=("$w") rss+=("$m")
  done
  python3 - "$out/$model.run1/manifest.json" "$model" "${walls[*]}" "${rss[*]}" <<'PY'
import json, statistics, sys
m = json.load(open(sys.argv[1]))
c = m["counts"]
wall = statistics.median(float(x) for x in sys.argv[3].split())
rss = statistics.median(float(x) for x in sys.argv[4].split()) / 1024  # MB (KiB in)
geo = c["geometry_bytes"] / 1e6
print(f"| {sys.argv[2]} | {c['triangles']:,} | {c['objects']:,} | {geo:.0f} | {wall:.2f} | "
      f"{c['triangles'] / wall / 1e6:.2f} | {rss:.0f} | {rss * 1.048576 / geo:.2f}x |")
PY
done
