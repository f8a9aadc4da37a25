"""Markdown for scripts/bench/cost_noise.sh: for each configuration run REPS
times on the same work, the spread of each client's per-frame cost over the
runs and the imbalance that this noise alone gives within a frame; the cost
is the stage threads' CPU time (and, for comparison, the stages' wall time).
Frames 1.. (frame 0 loads geometry).
usage: cost_noise_report.py OUT REPS label|clients|options..."""
import statistics as st
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from dmmr_bench.analysis import client_work, read_csv  # noqa: E402

out, reps = Path(sys.argv[1]), int(sys.argv[2])
configs = [c.split("|")[:2] for c in sys.argv[3:]]


def cpu(r, k):
    return client_work(r, k, "cpu")


def wall(r, k):
    return client_work(r, k, "wall")


print("| configuration | clients | same work in every run | cost | mean client cost ms (median over runs) "
      "| max/min of a client-frame over the runs (median) | (90th percentile) "
      "| noise-only max/mean within a frame (median) |")
print("|---|---|---|---|---|---|---|---|")
for label, n in configs:
    n = int(n)
    runs = [read_csv(out / f"{label}-r{r}.csv")[1:] for r in range(1, reps + 1)]
    frames = min(len(x) for x in runs)
    same = all(runs[0][f][f"c{k}_triangles"] == x[f][f"c{k}_triangles"] and
               runs[0][f][f"c{k}_queried"] == x[f][f"c{k}_queried"]
               for x in runs for f in range(frames) for k in range(1, n + 1))
    for name, fn in (("CPU", cpu), ("wall", wall)):
        spread, noise = [], []
        for f in range(frames):
            for k in range(1, n + 1):
                v = [fn(x[f], k) for x in runs]
                if min(v) > 0:
                    spread.append(max(v) / min(v))
            if n > 1:
                for x in runs:
                    rel = [fn(x[f], k) / max(1e-9, st.median(fn(y[f], k) for y in runs)) for k in range(1, n + 1)]
                    noise.append(max(rel) / st.fmean(rel))
        mean = st.median(st.fmean(st.fmean(fn(r, k) for k in range(1, n + 1)) for r in x) for x in runs)
        spread.sort()
        print(f"| {label} | {n} | {'yes' if same else 'no'} | {name} | {mean:.1f} | {st.median(spread):.3f} | "
              f"{spread[int(0.9 * (len(spread) - 1))]:.3f} | {st.median(noise):.3f} |" if noise else
              f"| {label} | {n} | {'yes' if same else 'no'} | {name} | {mean:.1f} | {st.median(spread):.3f} | "
              f"{spread[int(0.9 * (len(spread) - 1))]:.3f} | — |")
