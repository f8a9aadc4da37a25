#!/usr/bin/env bash
# Frame distribution strategies (--balance frustum, tiles-static,
# tiles-dynamic) on emulated networks (scripts/netem: every rank in its own
# network namespace, links shaped with tbf and delayed, MPI over TCP only),
# for a plant and a monument walkthrough with 1 to 16 clients, plus a
# tile-size sweep. Needs root (namespaces). Writes out/bench/tiles/ and prints
# the Markdown tables (scripts/bench/tiles_report.py).
#
#   scripts/bench/tiles.sh                 # everything below
#   CLIENTS="1 2 4" NETS="lan wifi" scripts/bench/tiles.sh   # a subset
#
# Networks: lan = 1 Gbit/s, 0.1 ms one way; wifi = 100 Mbit/s, 5 ms +- 1 ms
# (the Sensors 2022 paper's wireless cluster: ~100 Mbit/s usable, ms
# latency, jitter); slow = 20 Mbit/s, 10 ms +- 2 ms.
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}  # a copy keeps a rebuild from changing the binaries mid-run
out=out/bench/tiles
W=${DMMR_BENCH_W:-512}
H=${DMMR_BENCH_H:-384}
CLIENTS=${CLIENTS:-1 2 4 8 16}
NETS=${NETS:-lan wifi slow}
SCENES=${SCENES:-plant1m monument1m}
TILE=${TILE:-64x64}
SWEEP_TILES=${SWEEP_TILES:-32x32 64x64 128x128 256x256}
SWEEP_CLIENTS=${SWEEP_CLIENTS:-4}
SWEEP_NET=${SWEEP_NET:-wifi}
mkdir -p "$out" out/bench

scene() {  # name, scenegen arguments...
  local name=$1
  shift
  [ -f "out/bench/$name.osgb" ] || $bin/dmmr-scenegen "$@" -o "out/bench/$name.osgb" \
    --walkthrough "out/bench/$name.path" >/dev/null
  [ -d "out/bench/$name.scene" ] || $bin/dmmr-preprocess "out/bench/$name.osgb" \
    -o "out/bench/$name.scene" --no-progress >/dev/null
}
scene plant1m plant --seed 1 --triangles 1000000 --frames 16
scene monument1m monument --seed 1 --triangles 1000000 --frames 16

shape() {  # network name -> netem.sh shape options
  case $1 in
    lan) echo "--rate 1gbit --delay 0.1ms" ;;
    wifi) echo "--rate 100mbit --delay 5ms --jitter 1ms" ;;
    slow) echo "--rate 20mbit --delay 10ms --jitter 2ms" ;;
    *) echo "unknown network $1" >&2; exit 2 ;;
  esac
}

for s in $SCENES; do
  [ -d "$out/ref-$s" ] || $bin/dmmr-reference --scene "out/bench/$s.scene" --walkthrough "out/bench/$s.path" \
    --out "$out/ref-$s" --width "$W" --height "$H" --no-progress >/dev/null
done

trap 'scripts/netem/netem.sh down' EXIT
trap 'exit 1' INT TERM

run() {  # scene clients net label dmmr-render options...
  local s=$1 n=$2 net=$3 label=$4
  shift 4
  local name="$s-$net-c$n-$label"
  [ -f "$out/$name.cmp.csv" ] && return 0  # done in an earlier, interrupted run
  echo "tiles.sh: $name" >&2
  # Placement: mpirun-netem.sh runs mpirun --map-by node --bind-to none (one
  # rank per namespace, none bound to a core).
  LP_NUM_THREADS=1 scripts/netem/mpirun-netem.sh -x LP_NUM_THREADS -- $bin/dmmr-render \
    --scene "out/bench/$s.scene" --walkthrough "out/bench/$s.path" --out "$out/$name" \
    --width "$W" --height "$H" --stats "$out/$name.csv" --no-progress --client-timeout 300 "$@" \
    >"$out/$name.log" 2>&1
  $bin/dmmr-compare "$out/ref-$s" "$out/$name" --csv "$out/$name.cmp.csv" --min-psnr 0 \
    --max-diff-pixels 999999999 >/dev/null
}

for n in $CLIENTS; do
  scripts/netem/netem.sh down
  scripts/netem/netem.sh up "$n" >/dev/null
  for net in $NETS; do
    # shellcheck disable=SC2046
    scripts/netem/netem.sh shape $(shape "$net") >/dev/null
    for s in $SCENES; do
      run "$s" "$n" "$net" frustum --balance frustum
      run "$s" "$n" "$net" static --balance tiles-static --tile "$TILE"
      run "$s" "$n" "$net" dynamic --balance tiles-dynamic --tile "$TILE" --tiles-in-flight 2
      run "$s" "$n" "$net" dynamic1 --balance tiles-dynamic --tile "$TILE" --tiles-in-flight 1
      if [ "$n" = "$SWEEP_CLIENTS" ] && [ "$net" = "$SWEEP_NET" ]; then
        for t in $SWEEP_TILES; do
          run "$s" "$n" "$net" "static-$t" --balance tiles-static --tile "$t"
          run "$s" "$n" "$net" "dynamic-$t" --balance tiles-dynamic --tile "$t" --tiles-in-flight 2
        done
      fi
    done
  done
done
scripts/netem/netem.sh down
python3 scripts/bench/tiles_report.py "$out" --scenes "$SCENES" --clients "$CLIENTS" --nets "$NETS" \
  --tile "$TILE" --sweep-tiles "$SWEEP_TILES" --sweep-clients "$SWEEP_CLIENTS" --sweep-net "$SWEEP_NET"
