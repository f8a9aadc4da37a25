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

# The "user" cost: a client's CPU time less its stage threads' kernel time.
from dmmr_bench import analysis  # noqa: E402
from dmmr_bench.report import kernel_table  # noqa: E402

row = {"cull_ms": "1", "divide_ms": "1", "plan_cpu_ms": "0.5"}
for k, (vis, render, vsys, rsys) in enumerate([(2, 10, 0.5, 1.5), (1, 4, 0, 3)], start=1):
    row.update({f"c{k}_vis_cpu_ms": str(vis), f"c{k}_render_cpu_ms": str(render), f"c{k}_vis_sys_ms": str(vsys),
                f"c{k}_render_sys_ms": str(rsys), f"c{k}_bytes_sent": "0"})
check(analysis.has_kernel_time(row), "a row with kernel time is recognised")
check(analysis.client_work(row, 1, "cpu") == 12 and analysis.client_work(row, 1, "user") == 10,
      "user cost = CPU less kernel")
check(analysis.stage_work(row, 2, "render", "user") == 1, "a stage's user cost")
check(analysis.max_over_mean([row], 2, "cpu") == 12 / 8.5, "max/mean by CPU")
check(analysis.max_over_mean([row], 2, "user") == 10 / 6, "max/mean by user CPU: the kernel time moved it")
check(analysis.server_work(row, "user") == 0.5, "the server's plan CPU under the user cost")
check(not analysis.has_kernel_time({"c1_render_cpu_ms": "1"}), "older CSVs have no kernel time")
run = {"clients": 2, "plain": True, "options": [], "query_threshold": 0, "scheduled_efficiency": 0.5,
       "scheduled_user_efficiency": 0.625, "client_max_over_mean_median": 1.4,
       "client_max_over_mean_user_median": 1.2, "scheduled_user_frame_ms": 10.0,
       "per_client": [{"vis_cpu_ms": 2, "render_cpu_ms": 10, "sys_ms": 2, "faults_mean": 100},
                      {"vis_cpu_ms": 1, "render_cpu_ms": 4, "sys_ms": 3, "faults_mean": 1000}]}
kt = kernel_table([{"scene": "plants4", "runs": {"render-c2": run}}]).splitlines()
check(len(kt) == 3 and kt[2] == "| plants4 | 2 | 17.0 | 5.0 | 29.4% | 1,100 | 0.50 | 0.62 | 1.40 | 1.20 |",
      f"kernel table row: {kt}")
old_run = dict(run)
del old_run["scheduled_user_frame_ms"]
check(kernel_table([{"scene": "plants4", "runs": {"render-c2": old_run}}]) == "",
      "no table for runs without kernel time")

if failures:
    sys.exit(1)
print("bench_usage: all checks passed")
