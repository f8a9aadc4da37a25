#!/usr/bin/env python3
"""CTest bench_usage (label unit): dmmr-bench records each run's whole-process
CPU time and page faults (dmmr_bench.runner.run_cmd's `usage`) and lists them
in the report (dmmr_bench.report.usage_table)."""
import sys
import tempfile
from pathlib import Path

from bench_check import check, failures

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
from dmmr_bench.report import usage_table  # noqa: E402
from dmmr_bench.runner import run_cmd  # noqa: E402

with tempfile.TemporaryDirectory() as d:
    log = Path(d) / "bench.log"
    # A child that writes 64 MiB of fresh memory (16,384 pages) and spins a little.
    child = [sys.executable, "-c", "b = b'x' * (64 << 20)\nn = 0\nfor i in range(2_000_000): n += i"]
    usage = {}
    run_cmd(child, log, usage=usage)
    check(set(usage) == {"user_s", "sys_s", "minor_faults"}, f"usage keys {sorted(usage)}")
    check(usage["user_s"] > 0.01, f"the child's user time is counted: {usage}")
    check(usage["minor_faults"] >= 4096, f"the child's page faults are counted: {usage}")
    # Only this run's: a second, idle child adds far fewer faults than the first took.
    idle = {}
    run_cmd([sys.executable, "-c", "pass"], log, usage=idle)
    check(idle["minor_faults"] < usage["minor_faults"], f"each run counts its own: {idle} after {usage}")
    # A failing command still raises (and the usage stays the caller's to ignore).
    try:
        run_cmd([sys.executable, "-c", "raise SystemExit(3)"], log, usage={})
        check(False, "a failing command raises")
    except RuntimeError:
        pass

meta = {"run_usage": {"plants4/render-c16": {"user_s": 30.0, "sys_s": 10.0, "minor_faults": 1234567},
                      "plants4/render-c1": {"user_s": 8.0, "sys_s": 0.0, "minor_faults": 150000},
                      "plants4/render-c2": {"user_s": 0.0, "sys_s": 0.0, "minor_faults": 0}},
        "run_wall_s": {"plants4/render-c16": 20.5}}
table = usage_table(meta).splitlines()
check(len(table) == 5, f"a header, a rule and one row a run: {table}")
check(table[2] == "| plants4/render-c1 | — | 8.0 | 0.0 | 0.0% | 150,000 |", table[2])
check(table[3] == "| plants4/render-c2 | — | 0.0 | 0.0 | - | 0 |", f"client counts in order, no CPU: {table[3]}")
check(table[4] == "| plants4/render-c16 | 20.5 | 30.0 | 10.0 | 25.0% | 1,234,567 |", table[4])
check(len(usage_table({}).splitlines()) == 2, "no runs: the header alone")

if failures:
    sys.exit(1)
print("bench_usage: all checks passed")
