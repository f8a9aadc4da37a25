"""Markdown for scripts/bench/raytrace_scaling.sh: per tile strategy and size
and client count, the CPU-derived frame time (median over frames 2.. of the
server's cull + divide plus the busiest client's render-stage CPU time),
efficiency tau_1 / (S tau_S), the median max/mean of the clients' CPU time,
and the sum of the clients' CPU time against 1 client's (work inflation),
and the BVHs built per frame, summed over the clients (each client builds
those of the geometry its tiles show it, so they go on after the first
frames while objects move between clients' tiles). DMMR_BENCH_WARMUP
(default 2) frames are left out.
usage: raytrace_scaling_report.py OUT "COUNTS" """
import csv
import os
import statistics as st
import sys
from pathlib import Path

out, counts = Path(sys.argv[1]), [int(c) for c in sys.argv[2].split()]
FROM = int(os.environ.get("DMMR_BENCH_WARMUP", "2"))  # the first frames build the BVHs


def cpu(r, k):
    return float(r[f"c{k}_vis_cpu_ms"]) + float(r[f"c{k}_render_cpu_ms"])


def run(label, n):
    rows = list(csv.DictReader(open(out / f"{label}.csv")))[FROM:]
    derived = st.median(float(r["cull_ms"]) + float(r["divide_ms"]) + max(cpu(r, k) for k in range(1, n + 1))
                        for r in rows)
    mm = st.median(max(cpu(r, k) for k in range(1, n + 1)) / st.fmean(cpu(r, k) for k in range(1, n + 1))
                   for r in rows)
    total = st.median(sum(cpu(r, k) for k in range(1, n + 1)) for r in rows)
    builds = st.median(sum(float(r[f"c{k}_gpu_misses"]) for k in range(1, n + 1)) for r in rows)
    return derived, mm, total, builds


print("| tiles | size | clients | CPU-derived ms | speed-up | efficiency | max/mean client CPU | "
      "sum of client CPU vs 1 client | BVHs built a frame |")
print("|---|---|---|---|---|---|---|---|---|")
for bal in ["tiles-static", "tiles-dynamic"]:
    for tile in [128, 64]:
        base = None
        for n in counts:
            d, mm, total, builds = run(f"c{n}-{bal}-{tile}", n)
            if base is None:
                base = (d, total)
            print(f"| {bal.split('-')[1]} | {tile}x{tile} | {n} | {d:.1f} | {base[0] / d:.2f} | "
                  f"{base[0] / (n * d):.2f} | {mm:.2f} | {total / base[1]:.2f} | {builds:.0f} |")
