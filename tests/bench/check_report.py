#!/usr/bin/env python3
"""CTest bench_small: runs `dmmr-bench paper --scale small` and checks the
report's structure (files, JSON keys, Markdown tables, non-empty PNGs) and
its accuracy columns (conservative runs: 0 differing pixels), and that the
OpenSceneGraph baseline (osg-occlusion) ran beside the reference with the
ratios to it in the report. Not timings.

usage: check_report.py SOURCE_DIR BIN_DIR OUT_DIR"""
import json
import math
import sys
from pathlib import Path

from bench_check import check, failures, run_small

src, bin_dir, out = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3])


rep = run_small(src, bin_dir, out, "paper")

s = json.loads((rep / "summary.json").read_text())
for k in ("suite", "scale", "command", "machine", "width", "height", "wall_s", "configurations", "scenes",
          "accuracy_ok", "plots", "derived_definition", "cost"):
    check(k in s, f"summary.json has key {k}")
check(s.get("accuracy_ok") is True, "summary.json accuracy_ok is true")
labels = [c["label"] for c in s.get("configurations", [])]
for n in (1, 2, 4):
    check(f"render-c{n}" in labels, f"configuration render-c{n}")
check(any("--query-threshold" in c["options"] for c in s.get("configurations", [])), "a query-threshold sweep")
check(len(s.get("scenes", [])) >= 2, "at least two scenes")
for sc in s.get("scenes", []):
    name = sc["scene"]
    ref = sc["reference"]
    check(ref["frames"] > 1 and ref["frame_ms_mean"] > 0, f"{name}: reference frames and frame time")
    osg = sc.get("osg")
    check(osg is not None, f"{name}: osg-occlusion run")
    if osg:
        check(osg["frames"] == ref["frames"], f"{name}: osg-occlusion has as many frames as the reference")
        check(osg["frame_ms_mean"] > 0 and osg["triangles_mean"] > 0, f"{name}: osg-occlusion frame time, triangles")
        check(osg.get("speedup_vs_reference") is not None, f"{name}: osg-occlusion vs reference")
        check((rep / "csv" / f"{name}-osg-occlusion.csv").is_file(), f"csv/{name}-osg-occlusion.csv")
        frames = sorted((out / "runs" / name / "osg-occlusion").glob("frame_*.png"))
        check(len(frames) == ref["frames"], f"{name}: osg-occlusion wrote every frame ({len(frames)})")
    for label in labels:
        r = sc["runs"].get(label)
        check(r is not None, f"{name}: run {label}")
        if r is None:
            continue
        for k in ("frame_ms_mean", "fps", "derived_frame_ms_mean", "speedup_vs_reference",
                  "derived_speedup_vs_reference", "server", "per_client", "triangles_drawn_mean", "gpu_hit_rate",
                  "bytes_sent_mean", "accuracy", "speedup_vs_osg", "derived_speedup_vs_osg"):
            check(k in r, f"{name}/{label}: key {k}")
        check(len(r["per_client"]) == r["clients"], f"{name}/{label}: one entry per client")
        for c in r["per_client"]:
            for k in ("prepare_ms", "retrieve_ms", "pass_ms", "load_ms", "render_ms", "send_ms", "work_ms",
                      "triangles_mean", "bytes_sent_mean", "gpu_hit_rate", "vis_cpu_ms", "render_cpu_ms",
                      "cost_ms"):
                check(k in c, f"{name}/{label}: client key {k}")
            # every client renders and compresses a sub-frame each frame: its render thread used CPU
            check(c.get("render_cpu_ms", 0) > 0, f"{name}/{label}: render stage CPU time recorded")
        dc = r.get("derived_cpu_frame_ms_mean")
        check(dc is not None and dc > 0, f"{name}/{label}: derived time from CPU time")
        check(r["frames"] == ref["frames"], f"{name}/{label}: as many frames as the reference")
        check(r["accuracy"]["frames"] == ref["frames"], f"{name}/{label}: every frame compared")
        check(r["triangles_drawn_mean"] > 0, f"{name}/{label}: triangles drawn")
        if not r["options"]:
            # conservative (exact) visibility: frames identical to the reference
            check(r["accuracy"]["max_differing_pixels"] == 0, f"{name}/{label}: 0 differing pixels")
            check(r["accuracy"]["min_psnr_db"] == "inf", f"{name}/{label}: PSNR inf")
            check("derived_efficiency" in r and 0 < r["derived_efficiency"] < math.inf,
                  f"{name}/{label}: derived efficiency")
        else:
            p_ = r["accuracy"]["min_psnr_db"]
            check(p_ == "inf" or p_ > 15, f"{name}/{label}: approximate run's PSNR above 15 dB ({p_})")
        for f in (f"{name}-{label}.csv", f"{name}-{label}.cmp.csv"):
            check((rep / "csv" / f).is_file() and (rep / "csv" / f).stat().st_size > 0, f"csv/{f}")
    check((rep / "csv" / f"{name}-reference.csv").is_file(), f"csv/{name}-reference.csv")

for png in ("frame_time.png", "division_time.png", "query_prepare.png", "speed_error.png"):
    f = rep / "plots" / png
    ok = f.is_file() and f.stat().st_size > 1000 and f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    check(ok, f"plots/{png} is a non-empty PNG")
    check(f"plots/{png}" in s.get("plots", []), f"summary.json lists plots/{png}")

md = (rep / "report.md").read_text()
for heading in ("## Where dmmr stands", "## Summary", "## Stage times", "## Speed against error", "## Plots"):
    check(heading in md, f"report.md has '{heading}'")
tables = [l for l in md.splitlines() if l.startswith("|---")]
check(len(tables) >= 5, f"report.md has at least 5 Markdown tables ({len(tables)})")
for n in (1, 2, 4):
    check(f"#### dmmr with {n} client" in md, f"report.md has the {n}-client stage table")
check("derived" in md and "FAIL" not in md, "report.md labels derived times and has no accuracy FAIL")
check("osg-occlusion (osgViewer + OcclusionQueryNode)" in md and "vs osg-occlusion" in md,
      "report.md has the osg-occlusion baseline and the ratios to it")
check("osg" in s and s["osg"].get("tool") == "dmmr-osgviewer", "summary.json describes the OSG baseline")

print(f"bench_small: {len(failures)} failed checks; dmmr-bench wall {s.get('wall_s', 0):.1f} s")
sys.exit(1 if failures else 0)
