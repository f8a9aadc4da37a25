#!/usr/bin/env bash
# Two builds of dmmr-render side by side on one client's cost (CPU time, free
# of contention): the base build's dmmr-render with its defaults, this
# build's with its defaults, and this build's with each of DMMR_BENCH_VARIANTS
# (a |-separated list of option sets), taking turns, DMMR_BENCH_REPS times
# (default 4). Every run has llvmpipe rasterise on the calling thread
# (LP_NUM_THREADS=0), so the render stage thread's CPU time per frame
# (c1_render_cpu_ms, with fused stages the client's whole work) is the cost,
# whatever else runs on the machine. Scenes as scripts/bench/client_cost.sh
# makes them (run it once first); every frame is compared with the
# reference frames client_cost.sh left in out/bench/client-cost/SCENE-ref.
# usage: DMMR_BENCH_BASE_BIN=/path/to/base/build/bin scripts/bench/build_ab.sh
#        (writes out/bench/build-ab/, prints Markdown)
# DMMR_BENCH_SCENES (default "plant10m monument4m skulls25").
# DMMR_BENCH_SUITE=DIR takes the scenes from a dmmr-bench run instead
# (DIR/scenes/S.scene and .path, reference frames DIR/runs/S/reference; no
# exactly-visible column), e.g. out/bench/paper-medium with
# DMMR_BENCH_WIDTH=512 DMMR_BENCH_HEIGHT=384 and the suite's scene names.
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
base=${DMMR_BENCH_BASE_BIN:?DMMR_BENCH_BASE_BIN: the base build\'s bin directory}
out=${DMMR_BENCH_OUT:-out/bench/build-ab}
reps=${DMMR_BENCH_REPS:-4}
scenes=${DMMR_BENCH_SCENES:-plant10m monument4m skulls25}
refs=${DMMR_BENCH_REFS:-out/bench/client-cost}
IFS='|' read -r -a variants <<<"${DMMR_BENCH_VARIANTS:---predict off}"
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
suite=${DMMR_BENCH_SUITE:-}
view=(--width "${DMMR_BENCH_WIDTH:-${DMMR_BENCH_SIZE:-512}}"
  --height "${DMMR_BENCH_HEIGHT:-${DMMR_BENCH_SIZE:-512}}" --no-progress)
labels=(base new)
for i in "${!variants[@]}"; do labels+=("new$((i + 1))"); done
for r in $(seq 1 "$reps"); do
  for s in $scenes; do
    for l in "${labels[@]}"; do
      render=$bin/dmmr-render opts=()
      [ "$l" = base ] && render=$base/dmmr-render
      # shellcheck disable=SC2206
      [[ $l == new?* ]] && opts=(${variants[$((${l#new} - 1))]})
      scene=out/bench/$s.scene path=walkthroughs/$s.path ref=$refs/$s-ref
      [ -n "$suite" ] && scene=$suite/scenes/$s.scene path=$suite/scenes/$s.path \
        ref=$suite/runs/$s/reference
      "${mpi[@]}" -x LP_NUM_THREADS=0 "$render" --scene "$scene" \
        --walkthrough "$path" --out "$out/$s-$l" "${view[@]}" \
        --stats "$out/$s-$l-r$r.csv" "${opts[@]}"
      diff_frames "$ref" "$out/$s-$l" "$out/$s-$l-r$r.cmp.csv"
    done
  done
done
python3 - "$out" "$reps" "$refs" "${DMMR_BENCH_VARIANTS:---predict off}" "$suite" $scenes <<'PY'
import csv, os, statistics as st, sys
out, reps, refs, variants, suite, scenes = (sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4],
                                            sys.argv[5], sys.argv[6:])
labels = ["base", "new"] + [f"new{i + 1}" for i in range(len(variants.split("|")))]
names = {"base": "base build, defaults", "new": "this build, defaults"}
for i, v in enumerate(variants.split("|")):
    names[f"new{i + 1}"] = f"this build, `{v.strip()}`"
rows = lambda p: list(csv.DictReader(open(p)))[1:]
print("| scene | run | render thread CPU ms per frame (median of runs' means) | runs | "
      "slowest frame ms (median of runs) | triangles drawn per frame | drawn / exactly visible | "
      "worst differing pixels |")
print("|---|---|---|---|---|---|---|---|")
for s in scenes:
    exact_csv = f"{refs}/{s}-exact.csv"
    exact = (sum(float(r["exact_visible_triangles"]) for r in rows(exact_csv))
             if not suite and os.path.exists(exact_csv) else None)
    for l in labels:
        runs = [rows(f"{out}/{s}-{l}-r{r}.csv") for r in range(1, reps + 1)]
        cpu = [st.mean(float(x["c1_render_cpu_ms"]) for x in rs) for rs in runs]
        worst = st.median(max(float(x["c1_render_cpu_ms"]) for x in rs) for rs in runs)
        tris = st.median(sum(float(x["c1_triangles"]) for x in rs) for rs in runs)
        diff = max(int(d["differing_pixels"]) for r in range(1, reps + 1)
                   for d in csv.DictReader(open(f"{out}/{s}-{l}-r{r}.cmp.csv")))
        ratio = f"{tris / exact:.2f}" if exact else "n/a"
        print(f"| {s} | {names[l]} | {st.median(cpu):.1f} | {', '.join(f'{c:.1f}' for c in cpu)} | "
              f"{worst:.0f} | {tris / len(runs[0]):,.0f} | {ratio} | {diff} |")
PY
