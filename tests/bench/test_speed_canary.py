#!/usr/bin/env python3
"""CTest bench_speed_canary (label unit): scripts/bench/speed_canary.cpp's
probe prints, for each CPU in turn, the CPU time of its fixed arithmetic chain
and pointer chase (canary_runs.sh reads these columns), and bad arguments are a
usage error.

usage: test_speed_canary.py SPEED_CANARY"""
import os
import subprocess
import sys

from bench_check import check, failures

exe = sys.argv[1]
out = subprocess.run([exe, "probe", "0.25"], capture_output=True, text=True, timeout=60)
check(out.returncode == 0, f"probe exits 0: {out.returncode} {out.stderr}")
rows = [line.split() for line in out.stdout.splitlines() if line.strip()]
check(len(rows) >= 2, f"at least one round of samples: {rows}")
check(all(len(r) == 4 for r in rows), f"four columns a sample: {rows[:3]}")
cpus = {int(r[1]) for r in rows if len(r) == 4}
check(cpus and cpus <= set(range(os.cpu_count())), f"samples name online CPUs: {cpus}")
check(cpus >= os.sched_getaffinity(0), f"each CPU this test may use is sampled: {cpus}")
# The fixed work takes time on any machine: 300,000 dependent multiply-adds and
# 20,000 dependent loads are each well above a microsecond.
check(all(float(r[2]) > 1 and float(r[3]) > 1 for r in rows if len(r) == 4), f"positive timings: {rows[:3]}")
times = [float(r[0]) for r in rows if len(r) == 4]
check(times == sorted(times), "samples in time order")
for bad in ([], ["probe"], ["probe", "0"], ["touch", "-1"], ["fly", "1"]):
    r = subprocess.run([exe, *bad], capture_output=True, text=True, timeout=10)
    check(r.returncode == 2 and "usage" in r.stderr, f"{bad}: a usage error, exit 2 ({r.returncode})")

if failures:
    sys.exit(1)
print("bench_speed_canary: all checks passed")
