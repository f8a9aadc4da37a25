"""Markdown for scripts/bench/hetero.sh: per configuration, medians over rounds
of the mean over frames 8.. (the fit needs a few frames) of the CPU-derived
frame time (server cull + divide + the slowest client's stage-thread CPU
time), the scheduled frame time over the same frames (the run's own schedule,
--in-flight 3, replayed from the same costs: dmmr_bench.analysis.schedule),
each against the ideal, the median over frames of max/mean client CPU time,
client 2's share of the pixels, and the worst differing pixels against the
reference.
usage: hetero_report.py OUT REPS label|clients|slowed|options..."""
import csv
import statistics as st
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from dmmr_bench.analysis import client_work, derived_schedule, in_flight_of, server_work  # noqa: E402

out, reps, configs = Path(sys.argv[1]), int(sys.argv[2]), [c.split("|") for c in sys.argv[3:]]
FROM = 8


def cost(r, k):
    return client_work(r, k, "cpu")


def run(label, rep, n, options):
    every = list(csv.DictReader(open(out / f"{label}-r{rep}.csv")))
    rows = every[FROM:]
    derived = st.fmean(server_work(r, "cpu") + max(cost(r, k) for k in range(1, n + 1)) for r in rows)
    mm = st.median(max(cost(r, k) for k in range(1, n + 1)) / st.fmean(cost(r, k) for k in range(1, n + 1))
                   for r in rows)
    total = st.fmean(sum(cost(r, k) for k in range(1, n + 1)) for r in rows)
    px = sum(float(r[f"c{k}_bytes_raw"]) for r in rows for k in range(1, n + 1))
    share = sum(float(r["c2_bytes_raw"]) for r in rows) / px if n > 1 else 1.0
    diff = max(int(r["differing_pixels"]) for r in csv.DictReader(open(out / f"{label}-r{rep}.cmp.csv")))
    scheduled, _ = derived_schedule(every, n, in_flight_of(options), "cpu", first=FROM)
    return derived, mm, total, share, scheduled, diff


res = {}
for label, n, slow, options in configs:
    runs = [run(label, r, int(n), options) for r in range(1, reps + 1)]
    res[label] = [st.median(x[i] for x in runs) for i in range(5)] + [max(x[5] for x in runs)]
one, one_s = res[configs[0][0]][0], res[configs[0][0]][4]
print(f"1 client: {one:.1f} ms a frame (CPU-derived), {one_s:.1f} scheduled. Ideal for 4 clients of which one "
      f"is 2x slower (total speed 3.5): {one / 3.5:.1f} ms; for 4 equal clients: {one / 4:.1f} ms (each from "
      "the 1-client time of the same derivation).\n")
print("| run | options | client 2 | CPU-derived ms | vs ideal | scheduled ms | vs ideal (scheduled) | "
      "max/mean client CPU | sum of client CPU ms | client 2's share of the pixels | worst differing pixels |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for label, n, slow, options in configs:
    d, mm, total, share, sched, diff = res[label]
    speed = 3.5 if slow != "0" else int(n)
    print(f"| {label} | `{options}` | {'slowed 2x' if slow != '0' else 'normal'} | {d:.1f} | "
          f"{d / (one / speed):.2f} | {sched:.1f} | {sched / (one_s / speed):.2f} | "
          f"{mm:.2f} | {total:.1f} | {share:.3f} | {diff} |")
