"""Markdown for scripts/bench/raytrace.sh: per size and scene, the median
frame time (frames 4..) of the reference and of each configuration, and the
image error against the reference (mean and worst PSNR over frames, worst
differing pixels; the shadows change the image on purpose, so their error
says how much they change it).
usage: raytrace_report.py OUT "SIZES" "SCENES" label|options..."""
import csv
import math
import statistics as st
import sys
from pathlib import Path

out, sizes, scenes = Path(sys.argv[1]), sys.argv[2].split(), sys.argv[3].split()
configs = [c.split("|")[0] for c in sys.argv[4:]]
FROM = 4


def ms(name):
    rows = list(csv.DictReader(open(out / f"{name}.csv")))[FROM:]
    return st.median(float(r["frame_ms"]) for r in rows)


def err(name):
    rows = list(csv.DictReader(open(out / f"{name}.cmp.csv")))
    ps = [float(r["psnr"]) for r in rows]
    finite = [p for p in ps if math.isfinite(p)]
    mean = st.fmean(finite) if finite else math.inf
    return mean, min(ps), max(int(r["differing_pixels"]) for r in rows)


print("| size | scene | reference ms | " + " | ".join(f"{c} ms" for c in configs) +
      " | " + " | ".join(f"{c}: mean / worst PSNR, worst differing px" for c in configs) + " |")
print("|---|---|---|" + "---|" * (2 * len(configs)))
for size in sizes:
    for s in scenes:
        cells = [f"{ms(f'{s}-{size}-{c}'):.1f}" for c in configs]
        errs = []
        for c in configs:
            m, w, d = err(f"{s}-{size}-{c}")
            errs.append(f"{m:.1f} / {w:.1f} dB, {d}")
        print(f"| {size}x{size} | {s} | {ms(f'{s}-{size}-ref'):.1f} | " + " | ".join(cells) + " | " +
              " | ".join(errs) + " |")
