"""Shared by the bench CTest checks (check_report.py, check_scaling.py): a
failure list with check(), and a fresh dmmr-bench run of a suite's small
scale whose report files must exist."""
import shutil
import subprocess
import sys
from pathlib import Path

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print(f"FAIL: {what}", flush=True)


def run_small(src, bin_dir, out, suite, extra=()):
    """Runs `dmmr-bench SUITE --scale small [EXTRA...]` into a fresh `out`;
    exits when it left no report. Returns the report directory."""
    if out.exists():
        shutil.rmtree(out)  # a fresh run: the tool must generate its scenes too
    p = subprocess.run([sys.executable, str(Path(src) / "scripts" / "dmmr-bench"), suite, "--scale", "small",
                        "--bin", str(bin_dir), "--out", str(out), *extra])
    check(p.returncode == 0, f"dmmr-bench exit status {p.returncode} (0 expected)")
    rep = out / "report"
    for f in ("summary.json", "report.md"):
        check((rep / f).is_file() and (rep / f).stat().st_size > 0, f"report/{f} present and non-empty")
    if failures:
        sys.exit(1)
    return rep
