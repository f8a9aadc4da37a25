"""Markdown for scripts/bench/cost_validation.sh. Per scene and run: the mean
over frames 1.. of the derived frame time from CPU time and from the isolated
stage wall times (the same frames), their per-frame ratio (median), and for
the serial 1-client run the measured frame time against both derivations.
Medians over rounds.
usage: cost_validation_report.py OUT REPS"""
import csv
import statistics as st
import sys
from pathlib import Path

out, reps = Path(sys.argv[1]), int(sys.argv[2])
WALL = ["prepare_ms", "retrieve_ms", "load_ms", "render_ms", "readback_ms", "compress_ms"]


def f(r, k):
    return float(r[k])


def derived(r, n, cost):
    server = f(r, "cull_ms") + f(r, "divide_ms")
    if cost == "cpu":
        work = [f(r, f"c{k}_vis_cpu_ms") + f(r, f"c{k}_render_cpu_ms") for k in range(1, n + 1)]
    else:
        work = [sum(f(r, f"c{k}_{s}") for s in WALL) for k in range(1, n + 1)]
    return server + max(work)


def stats(path, n):
    rows = list(csv.DictReader(open(path)))[1:]
    cpu = [derived(r, n, "cpu") for r in rows]
    wall = [derived(r, n, "wall") for r in rows]
    return {"cpu": st.fmean(cpu), "wall": st.fmean(wall),
            "ratio": st.median(w / c for w, c in zip(wall, cpu) if c > 0),
            "measured": st.fmean(f(r, "frame_ms") for r in rows)}


print("| scene | run | derived from CPU time ms | derived from isolated wall ms | wall / CPU (median per frame) "
      "| measured frame ms | measured / CPU-derived | measured / wall-derived |")
print("|---|---|---|---|---|---|---|---|")
for s in ("plants4", "monuments25"):
    for label, n in (("turns-c1", 1), ("turns-c4", 4), ("serial-c1", 1)):
        runs = [stats(out / f"{s}-{label}-r{r}.csv", n) for r in range(1, reps + 1)]
        m = {k: st.median(x[k] for x in runs) for k in runs[0]}
        meas = (f"{m['measured']:.1f} | {m['measured'] / m['cpu']:.2f} | {m['measured'] / m['wall']:.2f}"
                if label.startswith("serial") else "— | — | —")
        print(f"| {s} | {label} | {m['cpu']:.1f} | {m['wall']:.1f} | {m['ratio']:.2f} | {meas} |")
