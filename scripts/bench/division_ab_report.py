"""Markdown for scripts/bench/division_ab.sh. Per scene, client count and
option set, medians over rounds of: the CPU-derived frame time (mean
over frames 1.. of the server's cull + divide plus the slowest client's
stage-thread CPU time; the server's is plan_cpu_ms where the CSV has it), efficiency tau_1 / (S tau_S) against the same round's
1-client run, the median over frames of max/mean client CPU time, max/mean of
the clients' mean CPU times over the walk (imbalance that lasts), the summed
client CPU time against 1 client (work inflation), and the worst differing
pixels against the reference over every round.
usage: division_ab_report.py OUT REPS "SCENES" clients|label|options..."""
import statistics as st
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from dmmr_bench.analysis import client_work, derived_schedule, in_flight_of, read_csv, server_work  # noqa: E402

out, reps, scenes = Path(sys.argv[1]), int(sys.argv[2]), sys.argv[3].split()
configs = [c.split("|") for c in sys.argv[4:]]
FROM = 1


def cost(r, k):
    return client_work(r, k, "cpu")


def run(scene, n, label, rep, options=""):
    base = out / f"{scene}-c{n}-{label}-r{rep}"
    every = read_csv(f"{base}.csv")
    rows = every[FROM:]
    ks = range(1, n + 1)
    derived = st.fmean(server_work(r, "cpu") + max(cost(r, k) for k in ks) for r in rows)
    mm = st.median(max(cost(r, k) for k in ks) / st.fmean(cost(r, k) for k in ks) for r in rows)
    means = [st.fmean(cost(r, k) for r in rows) for k in ks]
    lasting = max(means) / st.fmean(means)
    total = sum(means)
    diff = max(int(r["differing_pixels"]) for r in read_csv(f"{base}.cmp.csv"))
    scheduled, _ = derived_schedule(every, n, in_flight_of(options), "cpu")
    return derived, mm, lasting, total, diff, scheduled


print("| scene | clients | options | CPU-derived ms | efficiency | max/mean client (median over frames) "
      "| max/mean of the clients' means | client CPU vs 1 client | scheduled ms | efficiency (scheduled) "
      "| worst differing pixels |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for s in scenes:
    ones = [run(s, 1, "base", r) for r in range(1, reps + 1)]
    for n, label, *opts in configs:
        n = int(n)
        runs = [run(s, n, label, r, "|".join(opts)) for r in range(1, reps + 1)]
        eff = st.median(o[0] / (n * x[0]) for o, x in zip(ones, runs))
        infl = st.median(x[3] / o[3] for o, x in zip(ones, runs))
        med = [st.median(x[i] for x in runs) for i in range(3)]
        diff = max(x[4] for x in runs)
        sched = st.median(x[5] for x in runs)
        seff = st.median(o[5] / (n * x[5]) for o, x in zip(ones, runs))
        print(f"| {s} | {n} | {label} | {med[0]:.1f} | {eff:.2f} | {med[1]:.2f} | {med[2]:.2f} | {infl:.2f}x "
              f"| {sched:.1f} | {seff:.2f} | {diff} |")
