#!/usr/bin/env bash
# Machine speed beside repeated runs (issue 16): is a run's client CPU time
# the work's, or the machine's? Runs dmmr-render DMMR_BENCH_REPS times
# (default 4) for each client count in DMMR_BENCH_CLIENTS (default 1) on one
# scene, each beside `speed_canary probe` (scripts/bench/speed_canary.cpp:
# a fixed arithmetic chain and pointer chase timed by thread CPU time every
# 100 ms on each CPU); with DMMR_BENCH_TUNABLES set, each round also runs
# with GLIBC_TUNABLES set to it (label "tunables"). Every run with
# LP_NUM_THREADS=0, as the scaling suite. Prints Markdown: per run, the
# clients' stage-thread CPU per frame (summed over clients, frames 1..), its
# kernel part and minor page faults, and the probe's medians.
# DMMR_BENCH_SCENE: a .scene directory with a walkthrough beside it as
# NAME.path (the scaling suite's out/bench/scaling-*/scenes/), 1024x768.
# usage: DMMR_BENCH_SCENE=DIR scripts/bench/canary_runs.sh   (writes out/bench/canary/)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/canary}
reps=${DMMR_BENCH_REPS:-4}
counts=${DMMR_BENCH_CLIENTS:-1}
scene=${DMMR_BENCH_SCENE:?DMMR_BENCH_SCENE names a .scene directory}
path=${scene%.scene}.path
[ -f "$path" ] || { echo "canary_runs.sh: no walkthrough $path beside $scene" >&2; exit 1; }
# shellcheck source=lib.sh
source scripts/bench/lib.sh
mkdir -p "$out"
# The probe is a CMake target (tests/bench), built beside the tests; DMMR_BIN
# may name another build's tools, so the probe has its own variable.
canary=${DMMR_CANARY:-build/bin/speed_canary}
[ -x "$canary" ] || scripts/build.sh speed_canary
variants=plain
[ -n "${DMMR_BENCH_TUNABLES:-}" ] && variants="plain tunables"
for r in $(seq 1 "$reps"); do
  for n in $counts; do
    for v in $variants; do
      tag=$v-c$n-r$r
      "$canary" probe 600 >"$out/$tag.canary" &
      probe=$!
      tun=""
      [ "$v" = tunables ] && tun=$DMMR_BENCH_TUNABLES
      LP_NUM_THREADS=0 GLIBC_TUNABLES=$tun "${launch[@]}" -x LP_NUM_THREADS -x GLIBC_TUNABLES \
        -np $((n + 1)) "$bin/dmmr-render" --scene "$scene" --walkthrough "$path" --out "$out/frames" \
        --stats "$out/$tag.csv" --width 1024 --height 768 --backend osmesa --no-progress \
        --compress lz4 >"$out/$tag.log" 2>&1
      kill "$probe"
      wait "$probe" 2>/dev/null || true
    done
  done
done
python3 - "$out" <<'PY'
import csv, glob, re, statistics as st, sys
out = sys.argv[1]
print("| run | client CPU ms/frame | of it kernel ms | page faults/frame | probe arithmetic us (median) | probe chase us (median) |")
print("|---|---|---|---|---|---|")
key = lambda p: [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p)]
for f in sorted(glob.glob(f"{out}/*-c*-r*.csv"), key=key):
    rows = list(csv.DictReader(open(f)))[1:]
    n = 0
    while f"c{n + 1}_triangles" in rows[0]:
        n += 1
    per = lambda k: sum(float(r[f"c{c}_vis_{k}"]) + float(r[f"c{c}_render_{k}"]) for r in rows
                        for c in range(1, n + 1)) / len(rows)
    probe = [l.split() for l in open(f[:-4] + ".canary") if l.strip()]
    tag = f.split("/")[-1][:-4]
    print(f"| {tag} | {per('cpu_ms'):.1f} | {per('sys_ms'):.1f} | {per('faults'):,.0f} | "
          f"{st.median(float(p[2]) for p in probe):.0f} | {st.median(float(p[3]) for p in probe):.0f} |")
PY
