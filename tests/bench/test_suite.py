#!/usr/bin/env python3
"""CTest bench_suite (label unit): suite files are checked (dmmr_bench.suite):
bad TOML, unknown or misspelt keys, values of the wrong kind and missing
keys are one message naming the file and the key; the shipped suites pass;
and `dmmr-bench --report-only` on an empty output directory runs nothing."""
import subprocess
import sys
import tempfile
from pathlib import Path

from bench_check import check, failures

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))
from dmmr_bench.suite import SuiteError, load_suite  # noqa: E402

for shipped in sorted((ROOT / "configs" / "bench").glob("*.toml")):
    try:
        load_suite(shipped)
        check(True, f"{shipped.name} passes")
    except SuiteError as e:
        check(False, f"{shipped.name} passes: {e}")

GOOD = """[scales.small]
width = 64
height = 48
scenes = [{ name = "p", of = "plant", copies = 2 }]
"""
cases = [
    ("scales = [\n", "not valid TOML"),
    ("scales = 3\n", "scales: expected dict, got int 3"),
    (GOOD.replace("width = 64", "widht = 64"), "scales.small.widht: unknown key"),
    (GOOD.replace("width = 64\n", ""), "scales.small: missing width"),
    (GOOD.replace("width = 64", "width = \"64\""), "scales.small.width: expected int, got str"),
    (GOOD.replace("copies = 2", "copies = true"), "scenes[0].copies: expected int, got bool"),
    (GOOD.replace('name = "p", ', ""), "scenes[0]: missing name"),
    (GOOD.replace(", copies = 2", ""), "a replicate scene needs of and copies"),
    (GOOD + "[run]\ncost = \"cpu\"\nrepeat = 2\n", "run.repeat: unknown key"),
    ("[scales]\n", "no [scales] table"),
]
with tempfile.TemporaryDirectory() as d:
    for text, want in cases:
        p = Path(d) / "s.toml"
        p.write_text(text)
        try:
            load_suite(p)
            check(False, f"refused: {want}")
        except SuiteError as e:
            check(str(e).startswith(str(p)) and want in str(e), f"{want!r} in {e}")
    p = Path(d) / "s.toml"
    p.write_text(GOOD)
    load_suite(p)
    check(True, "a minimal suite passes")
    # --report-only with nothing there: an error naming what is missing, and no tool run
    # (argv[1]: the built tools' directory).
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "dmmr-bench"), str(p), "--out", str(Path(d) / "out"),
                        "--report-only", "--bin", sys.argv[1]], capture_output=True, text=True)
    check(r.returncode != 0 and "--report-only: scene p is missing" in r.stderr, f"report-only refuses: {r.stderr[-300:]}")
    check(not (Path(d) / "out" / "scenes" / "p.osgb").exists(), "and generated nothing")

sys.exit(1 if failures else 0)
