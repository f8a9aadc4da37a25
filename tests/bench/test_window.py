#!/usr/bin/env python3
"""CTest bench_window (label unit): the window of a longer walk that a scale
renders (dmmr_bench.runner.window_lines, path_frames, path_start)."""
import sys
from pathlib import Path

from bench_check import check, failures

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
from dmmr_bench.runner import Runner, window_lines  # noqa: E402

walk = [f"{i / 30.0!r} {i} 0 0 0 0 0 1" for i in range(10)]
w = window_lines(walk, 3, 4)
check([l.split()[1:] for l in w] == [l.split()[1:] for l in walk[3:7]], "points 3..6, eye and rotation kept")
check([float(l.split()[0]) for l in w] == [i / 30.0 - 3 / 30.0 for i in range(3, 7)], "times start at 0")
check(window_lines(walk, 0, 10) == walk, "the whole walk is itself")
for start, count in ((-1, 2), (8, 3), (0, 0), (0, 11)):
    try:
        window_lines(walk, start, count)
        check(False, f"window {start}+{count} of 10 points is refused")
    except ValueError as e:
        check("outside a walk of 10 points" in str(e), f"the error says why: {e}")


def runner(cfg):
    r = Runner.__new__(Runner)  # only the scale's table is read
    r.cfg = cfg
    return r


r = runner({"frames": 40, "path_frames": 200})
check(r.path_frames({}) == 200 and r.path_start({}) == 80, "the middle 40 of 200 points by default")
check(r.path_start({"path_start": 0}) == 0, "a scene may start the window elsewhere")
r = runner({"frames": 8})
check(r.path_frames({}) == 8 and r.path_start({}) == 0, "without path_frames the walk is the frames")
for cfg, sc in (({"frames": 40, "path_frames": 20}, {}), ({"frames": 40, "path_frames": 200}, {"path_start": 161})):
    try:
        runner(cfg).path_start(sc)
        check(False, f"{cfg} {sc} is refused")
    except SystemExit as e:
        check("dmmr-bench: path_" in str(e), f"the error names the key: {e}")

if failures:
    sys.exit(1)
print("bench_window: all checks passed")
