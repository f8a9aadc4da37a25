#!/usr/bin/env python3
"""CTest bench_schedule (label unit): dmmr_bench.analysis.schedule, the
replay of dmmr's frame schedule behind the scaling report's scheduled frame
time, on cases worked out by hand."""
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
from dmmr_bench.analysis import in_flight_of, schedule  # noqa: E402

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print(f"FAIL: {what}", flush=True)


def close(a, b):
    return math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-12)


zero2 = [[0.0, 0.0]] * 8
# Two clients whose costs alternate 10/2 and 2/10: every frame's slowest
# client takes 10, but each client's mean is 6. Frames in flight let each
# client run ahead, so the period is 6; with one frame in flight every frame
# waits for its slowest client: 10.
alt = [[10.0, 2.0] if f % 2 == 0 else [2.0, 10.0] for f in range(8)]
period, latency = schedule([0.0] * 8, alt, zero2, in_flight=1)
check(close(period, 10.0), f"in flight 1: period {period} (10 expected)")
check(close(latency, 10.0), f"in flight 1: latency {latency} (10 expected)")
period, _ = schedule([0.0] * 8, alt, zero2, in_flight=1, first=4)
check(close(period, 10.0), f"in flight 1, from frame 4: period {period} (10 expected)")
period, _ = schedule([0.0] * 8, alt, zero2, in_flight=3, first=2)
check(close(period, (48.0 - 12.0) / 6), f"in flight 3, from frame 2: period {period} (6 expected)")
period, _ = schedule([0.0] * 8, alt, zero2, in_flight=3)
# Client 1 ends its jobs at 10, 12, 22, 24, 34, 36, 46, 48 and client 2 at
# 2, 12, 14, 24, ...; frames are done at 10, 12, 22, 24, 34, 36, 46, 48.
check(close(period, (48.0 - 10.0) / 7), f"in flight 3: period {period} ({38 / 7} expected)")
# Equal, steady clients: the period is the client's cost whatever in flight is.
for k in (1, 2, 3, 5):
    p, _ = schedule([0.0] * 6, [[4.0, 4.0]] * 6, [[0.0, 0.0]] * 6, in_flight=k)
    check(close(p, 4.0), f"steady clients, in flight {k}: period {p} (4 expected)")
# The server plans serially: with planning dearer than any client, the
# period is the planning time; the transfer keeps a client busy too.
p, _ = schedule([7.0] * 6, [[1.0, 2.0]] * 6, [[0.0, 0.0]] * 6, in_flight=3)
check(close(p, 7.0), f"server-bound: period {p} (7 expected)")
p, lat = schedule([1.0] * 6, [[3.0, 2.0]] * 6, [[0.5, 2.0]] * 6, in_flight=1)
check(close(p, 5.0) and close(lat, 5.0), f"in flight 1, transfer: period {p}, latency {lat} (5, 5 expected)")
# On random costs: one frame in flight is exactly the serial sum (no
# overlap: each frame is planned once the previous one is assembled); more
# frames in flight never make the run slower (every start is a max of sums,
# and earlier releases can only make it earlier); never negative latency.
import random  # noqa: E402
rng = random.Random(16)
for trial in range(200):
    frames, n = rng.randint(2, 30), rng.randint(1, 6)
    srv = [rng.uniform(0, 2) for _ in range(frames)]
    cl = [[rng.uniform(0, 20) for _ in range(n)] for _ in range(frames)]
    tr = [[rng.uniform(0, 1) for _ in range(n)] for _ in range(frames)]
    serial = sum(srv[f] + max(cl[f][j] + tr[f][j] for j in range(n)) for f in range(1, frames))
    periods = []
    for k in (1, 2, 3, 4):
        p, lat = schedule(srv, cl, tr, k)
        periods.append(p)
        check(lat >= 0, f"trial {trial}, in flight {k}: latency {lat} < 0")
    check(math.isclose(periods[0] * (frames - 1), serial, rel_tol=1e-9),
          f"trial {trial}: in flight 1 period {periods[0]} is not the serial {serial / (frames - 1)}")
    check(all(b <= a + 1e-9 for a, b in zip(periods, periods[1:])),
          f"trial {trial}: more frames in flight was slower: {periods}")
check(in_flight_of(["--in-flight", "2"]) == 2 and in_flight_of("--weights fitted") == 3
      and in_flight_of("--in-flight=5") == 5 and in_flight_of(None) == 3, "in_flight_of")

print(f"bench_schedule: {len(failures)} failed checks")
sys.exit(1 if failures else 0)
