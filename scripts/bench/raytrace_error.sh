#!/usr/bin/env bash
# Ray-traced image error against the raster reference, effects off (issue
# 18), on every scene of the medium paper suite (configs/bench/paper.toml:
# plants4/6/8, monuments16/25/36, 512x384, 80 frames): PSNR (mean and worst
# over frames) and differing pixels (worst frame, and the mean share of the
# frame). The suite's scenes and reference frames are reused from
# out/bench/paper-medium (scripts/dmmr-bench paper --scale medium) when there,
# and made otherwise.
# usage: scripts/bench/raytrace_error.sh   (writes out/bench/raytrace-error/, prints Markdown)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/raytrace-error}
suite=out/bench/paper-medium
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
if [ ! -d "$suite/scenes/monuments36.scene" ]; then
  scripts/dmmr-bench paper --scale medium --out "$suite" >/dev/null
fi
names="plants4 plants6 plants8 monuments16 monuments25 monuments36"
for s in $names; do
  ref=$suite/runs/$s/reference
  if [ ! -f "$ref/frame_000079.png" ]; then
    ref=$out/$s-ref
    $bin/dmmr-reference --scene "$suite/scenes/$s.scene" --walkthrough "$suite/scenes/$s.path" \
      --out "$ref" --width 512 --height 384 --no-progress
  fi
  "${mpi[@]}" $bin/dmmr-render --scene "$suite/scenes/$s.scene" --walkthrough "$suite/scenes/$s.path" \
    --out "$out/$s" --width 512 --height 384 --renderer raytrace --no-progress --stats "$out/$s.csv"
  $bin/dmmr-compare "$ref" "$out/$s" --csv "$out/$s.cmp.csv" --min-psnr 0 \
    --max-diff-pixels 999999999 >/dev/null
done
python3 - "$out" $names <<'PY'
import csv, math, statistics as st, sys
from pathlib import Path
out = Path(sys.argv[1])
print("| scene | frames | mean PSNR dB | worst PSNR dB | worst differing pixels | mean differing share |")
print("|---|---|---|---|---|---|")
for s in sys.argv[2:]:
    rows = list(csv.DictReader(open(out / f"{s}.cmp.csv")))
    ps = [float(r["psnr"]) for r in rows]
    d = [int(r["differing_pixels"]) for r in rows]
    fin = [p for p in ps if math.isfinite(p)]
    print(f"| {s} | {len(rows)} | {st.fmean(fin):.1f} | {min(ps):.1f} | {max(d)} | "
          f"{100 * st.fmean(d) / (512 * 384):.2f}% |")
PY
