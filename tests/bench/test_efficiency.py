#!/usr/bin/env python3
"""CTest bench_efficiency (label unit): the scaling report's account of where
the efficiency goes (dmmr_bench.analysis.efficiency_parts,
slowest_client_profile, share_correlation, and report.efficiency_table), on
cases worked out by hand and a fixed-seed randomized identity."""
import json
import math
import random
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
from dmmr_bench import analysis  # noqa: E402
from dmmr_bench.analysis import efficiency_parts, share_correlation, slowest_client_profile  # noqa: E402
from dmmr_bench.report import efficiency_table  # noqa: E402

failures = []
analysis.COST = "cpu"  # client_work = vis CPU + render CPU


def check(cond, what):
    if not cond:
        failures.append(what)
        print(f"FAIL: {what}", flush=True)


def close(a, b):
    return a is not None and math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)


def row(costs, **figures):
    """A stats row of len(costs) clients: render CPU = cost; each figure a list, one value per client."""
    r = {"plan_cpu_ms": "0.5"}
    for k, c in enumerate(costs, 1):
        r[f"c{k}_vis_cpu_ms"] = "0"
        r[f"c{k}_render_cpu_ms"] = repr(c)
        r[f"c{k}_bytes_sent"] = "0"
        for name, vals in figures.items():
            r[f"c{k}_{name}"] = repr(vals[k - 1])
    return r


# --- slowest_client_profile ---------------------------------------------------
# Client 2 is slowest in every frame; it draws twice the triangles of the
# others, its region has as many pixels, and its object list the same size.
rows = [row([1.0, 2.0, 1.0, 1.0], triangles=[10, 20, 10, 10], bytes_raw=[300, 300, 300, 300],
            objects=[5, 5, 5, 5], visible=[0, 0, 0, 0]) for _ in range(5)]
p = slowest_client_profile(rows, analysis.client_costs(rows, 4))
check(close(p["cost"], 2.0 / 1.25), f"slowest cost over mean {p['cost']} (1.6 expected)")
check(close(p["triangles"], 20 / 12.5), f"slowest triangles over mean {p['triangles']} (1.6 expected)")
check(close(p["pixels"], 1.0), f"slowest pixels over mean {p['pixels']} (1 expected)")
check(close(p["objects"], 1.0), f"slowest objects over mean {p['objects']} (1 expected)")
check(p["visible"] is None, f"no frame draws an object: no ratio ({p['visible']})")
check(p["submitted"] is None, f"a figure the CSV lacks has no ratio ({p['submitted']})")
# The slowest client moves from frame to frame: the ratio follows it.
rows = [row([3.0, 1.0], triangles=[30, 10]), row([1.0, 3.0], triangles=[10, 30]), row([1.0, 3.0], triangles=[30, 10])]
p = slowest_client_profile(rows, analysis.client_costs(rows, 2))
check(close(p["cost"], 1.5), f"moving slowest client: cost ratio {p['cost']} (1.5 expected)")
# frames 1 and 2: 1.5; frame 3: the slowest (client 2) drew 10 of a mean 20: 0.5; median 1.5
check(close(p["triangles"], 1.5), f"moving slowest client: triangles ratio {p['triangles']} (1.5 expected)")

# --- share_correlation --------------------------------------------------------
# The same client slow every frame: its share repeats exactly at any lag.
steady = [[2.0, 1.0, 1.0]] * 9
check(close(share_correlation(steady, 1), 1.0),
      f"a persistent slow client: correlation {share_correlation(steady, 1)} (1 expected)")
# Two clients alternating: shares anticorrelate at lag 1 and repeat at lag 2.
alt = [[3.0, 1.0] if f % 2 == 0 else [1.0, 3.0] for f in range(8)]
check(close(share_correlation(alt, 1), -1.0), f"alternating, lag 1: {share_correlation(alt, 1)} (-1 expected)")
check(close(share_correlation(alt, 2), 1.0), f"alternating, lag 2: {share_correlation(alt, 2)} (1 expected)")
check(share_correlation(alt[:1], 1) is None, "one frame: no pairs, no correlation")
even = [[1.0, 1.0]] * 6
check(share_correlation(even, 1) is None, "equal shares: no spread, no correlation")

# --- efficiency_parts: missing or zero figures ---------------------------------
check(efficiency_parts({"clients": 1}, {"clients": 2}) is None, "missing figures: None")
check(efficiency_parts({"derived_frame_ms_mean": 1, "client_cost_sum_mean": 0},
                       {"clients": 2, "derived_frame_ms_mean": 1, "client_cost_sum_mean": 1,
                        "client_cost_max_mean": 1}) is None, "a zero figure: None")

# --- slowest_client_profile: frames where nobody worked ------------------------
idle = [row([0.0, 0.0], triangles=[10, 30]), row([1.0, 3.0], triangles=[10, 30])]
p = slowest_client_profile(idle, analysis.client_costs(idle, 2))
check(close(p["triangles"], 1.5), f"an idle frame has no slowest client: triangles {p['triangles']} (1.5 expected)")

# --- from CSV rows through render_stats, and the report's table ----------------
# Two clients alternating 3 / 1 ms (per-frame balance 4/2/3 = 0.667), summed
# work 4 against the 1-client run's 3.5 (1 / inflation 0.875).
import csv  # noqa: E402
import tempfile  # noqa: E402

with tempfile.TemporaryDirectory() as tmp:
    def write(name, rows):
        path = Path(tmp) / name
        with open(path, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            for r in rows:
                w.writerow(r)
        return path

    def full(costs, plan=0.5, sent=None):
        n = len(costs)
        z = [0] * n
        r = row(costs, triangles=[100 * c for c in costs], bytes_raw=[300] * n, objects=z, queried=z,
                visible=z, occluders=z, bytes_sent=sent or z, submitted=z)
        r["plan_cpu_ms"] = repr(plan)
        return r

    one = analysis.render_stats(write("c1.csv", [full([3.5]) for _ in range(7)]), 1)
    two = analysis.render_stats(write("c2.csv", [full([3.0, 1.0] if f % 2 else [1.0, 3.0]) for f in range(7)]), 2)
    check(close(one["client_cost_sum_mean"], 3.5), f"1 client: summed work {one['client_cost_sum_mean']}")
    check(close(two["client_cost_max_mean"], 3.0), f"2 clients: largest work {two['client_cost_max_mean']}")
    p = efficiency_parts(one, two)
    # each frame: plan 0.5 ms, nothing sent; 1 client 0.5 + 3.5, 2 clients 0.5 + 3
    check(close(p["one_client"], 4.0 / 3.5), f"1-client frame over its work {p['one_client']} (8/7 expected)")
    check(close(p["work"], 3.5 / 4.0), f"1 / inflation {p['work']} (0.875 expected)")
    check(close(p["balance"], 2.0 / 3.0), f"balance {p['balance']} (2/3 expected)")
    check(close(p["server"], 3.0 / 3.5), f"slowest client over the frame {p['server']} (6/7 expected)")
    check(close(p["efficiency"], one["derived_frame_ms_mean"] / (2 * two["derived_frame_ms_mean"])),
          "efficiency from the derived frame times")
    check(close(two["share_correlation"][1], -1.0), f"render_stats' lag-1 correlation {two['share_correlation']}")
    two["efficiency_parts"], two["plain"], two["options"] = p, True, []
    # the report reads the JSON summary, whose keys are strings
    two = json.loads(json.dumps(two))
    scene = {"scene": "alt", "runs": {"render-c1": dict(one, plain=True, options=[]), "render-c2": two}}
    table = efficiency_table([scene])
    line = next((ln for ln in table.splitlines() if ln.startswith("| alt | 2 |")), "")
    check(" 0.88 | 0.67 |" in line, f"the table's row shows 1 / inflation and balance: {line!r}")
    # alternating shares: anticorrelated at every odd lag, 1 and 3
    check(line.rstrip().endswith("| -1.00 | -1.00 (3) |"), f"the table's row ends with both correlations: {line!r}")

    # Fixed-seed random runs through render_stats, with the server's plan and
    # the sub-frames' transfer in the derived frame: the four factors multiply
    # to the efficiency, the 1-client frame is at least its work, the mean
    # client at most the slowest, and the slowest client's work at most the frame.
    rng = random.Random(16)
    for trial in range(60):
        s_ = rng.choice([2, 3, 4, 8, 16])
        frames = rng.randint(2, 9)
        base_rows = [full([rng.uniform(0.1, 80)], plan=rng.uniform(0, 5), sent=[rng.randint(0, 400000)])
                     for _ in range(frames)]
        run_rows = [full([rng.choice([0.0, rng.uniform(0.1, 30)]) for _ in range(s_)], plan=rng.uniform(0, 5),
                         sent=[rng.randint(0, 100000) for _ in range(s_)]) for _ in range(frames)]
        b = analysis.render_stats(write(f"b{trial}.csv", base_rows), 1)
        r = analysis.render_stats(write(f"r{trial}.csv", run_rows), s_)
        p = efficiency_parts(b, r)
        if p is None:
            continue  # a run whose clients all cost 0
        want = b["derived_frame_ms_mean"] / (s_ * r["derived_frame_ms_mean"])
        prod = p["one_client"] * p["work"] * p["balance"] * p["server"]
        if not (close(prod, want) and close(p["efficiency"], want)):
            check(False, f"trial {trial}: product {prod}, efficiency {p['efficiency']}, expected {want}")
            break
        if not (p["one_client"] >= 1 - 1e-12 and p["balance"] <= 1 + 1e-12 and p["server"] <= 1 + 1e-12):
            check(False, f"trial {trial}: a factor out of range {p}")
            break

if failures:
    print(f"{len(failures)} check(s) failed")
    sys.exit(1)
print("all checks passed")
