#!/usr/bin/env python3
"""CTest bench_repeats (label unit): how dmmr-bench --repeats names a
configuration's runs and picks the one whose figures it reports
(dmmr_bench.analysis.run_labels, median_run)."""
import sys
from pathlib import Path

from bench_check import check, failures

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
from dmmr_bench.analysis import median_run, run_labels, run_order  # noqa: E402

check(run_labels("render-c4", 1) == ["render-c4"], "one run keeps the plain label")
check(run_labels("render-c16", 3) == ["render-c16", "render-c16.r2", "render-c16.r3"], "repeats .r2, .r3")
check(run_order(["render-c1", "render-c4"], 1) == [("render-c1", "render-c1"), ("render-c4", "render-c4")],
      "one round: the configurations in order")
check(run_order(["render-c1", "render-c4"], 3) ==
      [("render-c1", "render-c1"), ("render-c4", "render-c4"), ("render-c1", "render-c1.r2"),
       ("render-c4", "render-c4.r2"), ("render-c1", "render-c1.r3"), ("render-c4", "render-c4.r3")],
      "repeats in rounds: no configuration runs twice in a row")
check(median_run([7.0]) == 0, "a single run is its own median")
check(median_run([30.0, 10.0, 20.0]) == 2, "the middle of three by cost, wherever it ran")
check(median_run([40.0, 10.0, 30.0, 20.0]) == 3, "the lower middle of an even count")
check(median_run([5.0, 5.0, 5.0]) == 1, "ties keep run order")
# one slow outlier (a busy machine) never decides the figures
costs = [220.0, 346.0, 231.0, 212.0, 236.0]
check(costs[median_run(costs)] == 231.0, "an outlier run is not the one reported")
try:
    median_run([])
    check(False, "no runs is an error")
except ValueError:
    pass

if failures:
    sys.exit(1)
print("bench_repeats: all checks passed")
