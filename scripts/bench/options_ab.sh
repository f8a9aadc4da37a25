#!/usr/bin/env bash
# Option sets of dmmr-render side by side by wall time, 1 client, on a
# dmmr-bench suite's scenes: each of DMMR_BENCH_VARIANTS (a |-separated list
# of option sets) takes turns with the others, DMMR_BENCH_REPS times
# (default 3), with llvmpipe's threads as the suite ran them
# (LP_NUM_THREADS, default 1 as in `dmmr-bench paper`). Wall time, not CPU
# time, because what is compared (for example --flush-triangles) changes how
# the render stage and llvmpipe's threads overlap, which a stage's CPU time
# does not show. dmmr-reference runs DMMR_BENCH_REF_REPS times (default 1)
# with each of DMMR_BENCH_REF_VARIANTS. Every frame is compared with the
# suite's reference frames.
# usage: DMMR_BENCH_SUITE=out/bench/paper-medium scripts/bench/options_ab.sh
#        (writes out/bench/options-ab/, prints Markdown)
# DMMR_BENCH_SCENES (default: the paper suite's medium scenes),
# DMMR_BENCH_WIDTH and DMMR_BENCH_HEIGHT (default 512x384, the suite's).
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
suite=${DMMR_BENCH_SUITE:?DMMR_BENCH_SUITE: a dmmr-bench output directory (scenes/, runs/)}
out=${DMMR_BENCH_OUT:-out/bench/options-ab}
reps=${DMMR_BENCH_REPS:-3}
ref_reps=${DMMR_BENCH_REF_REPS:-1}
lp=${LP_NUM_THREADS:-1}
scenes=${DMMR_BENCH_SCENES:-plants4 plants6 plants8 monuments16 monuments25 monuments36}
variants_text=${DMMR_BENCH_VARIANTS:---flush-triangles 0|--flush-triangles auto}
ref_variants_text=${DMMR_BENCH_REF_VARIANTS:---flush-triangles 0|--flush-triangles auto}
IFS='|' read -r -a variants <<<"$variants_text"
IFS='|' read -r -a ref_variants <<<"$ref_variants_text"
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
view=(--width "${DMMR_BENCH_WIDTH:-512}" --height "${DMMR_BENCH_HEIGHT:-384}" --no-progress)
for r in $(seq 1 "$reps"); do
  for s in $scenes; do
    scene=$suite/scenes/$s.scene path=$suite/scenes/$s.path ref=$suite/runs/$s/reference
    for i in "${!variants[@]}"; do
      # shellcheck disable=SC2206
      opts=(${variants[$i]})
      "${mpi[@]}" -x LP_NUM_THREADS="$lp" "$bin/dmmr-render" --scene "$scene" --walkthrough "$path" \
        --out "$out/$s-v$i" "${view[@]}" --stats "$out/$s-v$i-r$r.csv" "${opts[@]}"
      diff_frames "$ref" "$out/$s-v$i" "$out/$s-v$i-r$r.cmp.csv"
    done
    if [ "$r" -le "$ref_reps" ]; then
      for i in "${!ref_variants[@]}"; do
        # shellcheck disable=SC2206
        opts=(${ref_variants[$i]})
        LP_NUM_THREADS=$lp $bin/dmmr-reference --scene "$scene" --walkthrough "$path" \
          --out "$out/$s-ref$i" "${view[@]}" --stats "$out/$s-ref$i-r$r.csv" "${opts[@]}"
        diff_frames "$ref" "$out/$s-ref$i" "$out/$s-ref$i-r$r.cmp.csv"
      done
    fi
  done
done
python3 - "$out" "$reps" "$ref_reps" "$variants_text" "$ref_variants_text" $scenes <<'PY'
import csv, statistics as st, sys
out, reps, ref_reps, variants, ref_variants, scenes = (sys.argv[1], int(sys.argv[2]),
    int(sys.argv[3]), sys.argv[4].split("|"), sys.argv[5].split("|"), sys.argv[6:])
rows = lambda p: list(csv.DictReader(open(p)))[1:]  # frame 0 (cold caches) left out
med = lambda p, k: st.median(float(x[k]) for x in rows(p))
print("| scene | run | frame ms (median of runs' medians) | runs | vs the first | "
      "client render ms | triangles drawn per frame | worst differing pixels |")
print("|---|---|---|---|---|---|---|---|")
for s in scenes:
    first = None
    for i, v in enumerate(variants):
        runs = [med(f"{out}/{s}-v{i}-r{r}.csv", "frame_ms") for r in range(1, reps + 1)]
        f = st.median(runs)
        first = first or f
        render = st.median(med(f"{out}/{s}-v{i}-r{r}.csv", "c1_render_ms") for r in range(1, reps + 1))
        tris = st.median(med(f"{out}/{s}-v{i}-r{r}.csv", "c1_triangles") for r in range(1, reps + 1))
        diff = max(int(d["differing_pixels"]) for r in range(1, reps + 1)
                   for d in csv.DictReader(open(f"{out}/{s}-v{i}-r{r}.cmp.csv")))
        print(f"| {s} | dmmr-render `{v.strip()}` | {f:.1f} | {', '.join(f'{x:.1f}' for x in runs)} | "
              f"{first / f:.2f}x | {render:.1f} | {tris:,.0f} | {diff} |")
    for i, v in enumerate(ref_variants):
        runs = [med(f"{out}/{s}-ref{i}-r{r}.csv", "frame_ms") for r in range(1, ref_reps + 1)]
        diff = max(int(d["differing_pixels"]) for r in range(1, ref_reps + 1)
                   for d in csv.DictReader(open(f"{out}/{s}-ref{i}-r{r}.cmp.csv")))
        print(f"| {s} | dmmr-reference `{v.strip()}` | {st.median(runs):.1f} | "
              f"{', '.join(f'{x:.1f}' for x in runs)} | | | | {diff} |")
PY
