"""Markdown for scripts/bench/raytrace_stride.sh: per scene and stride, the
median frame time and tracing time (frames 4..), the speed-up over stride 1
in the same run, and the error against the stride-1 frames and against the
raster reference (mean and worst PSNR over frames, worst differing pixels).
usage: raytrace_stride_report.py OUT "SCENES" "STRIDES\""""
import csv
import math
import statistics as st
import sys
from pathlib import Path

out, scenes, strides = Path(sys.argv[1]), sys.argv[2].split(), sys.argv[3].split()
FROM = 4


def median(name, column):
    rows = list(csv.DictReader(open(out / f"{name}.csv")))[FROM:]
    return st.median(float(r[column]) for r in rows)


def err(name):
    rows = list(csv.DictReader(open(out / f"{name}.cmp.csv")))
    ps = [float(r["psnr"]) for r in rows]
    finite = [p for p in ps if math.isfinite(p)]
    mean = st.fmean(finite) if finite else math.inf
    return f"{mean:.1f} / {min(ps):.1f} dB, {max(int(r['differing_pixels']) for r in rows)}"


print("| scene | stride | rays | frame ms | tracing ms | speed-up (frame) | vs stride 1: mean / worst "
      "PSNR, worst differing px | vs raster reference: mean / worst PSNR, worst differing px |")
print("|---|---|---|---|---|---|---|---|")
for s in scenes:
    base = median(f"{s}-s1", "frame_ms")
    for n in strides:
        name = f"{s}-s{n}"
        frame, trace = median(name, "frame_ms"), median(name, "c1_render_ms")
        print(f"| {s} | {n} | 1/{int(n) ** 2} | {frame:.1f} | {trace:.1f} | {base / frame:.2f}x | "
              f"{err(f'{name}-vs-s1')} | {err(f'{name}-vs-ref')} |")
