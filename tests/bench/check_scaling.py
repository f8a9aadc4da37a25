#!/usr/bin/env python3
"""CTest bench_scaling_small: runs `dmmr-bench scaling --scale small
--repeats 2` and checks the scaling report's structure (measurement method,
targets checklist, scaling, inflation, repeats and breakdown tables,
summary.json keys) and its accuracy (every frame of every run identical to
the reference). Never timings: the targets' met / not met depend on the
machine, only their presence is checked.

usage: check_scaling.py SOURCE_DIR BIN_DIR OUT_DIR"""
import json
import sys
from pathlib import Path

from bench_check import check, failures, run_small

src, bin_dir, out = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3])
CLIENTS = [1, 2, 4, 8, 16]
WORK = ("queried", "visible", "triangles", "occluders", "pixels", "cpu_ms")


rep = run_small(src, bin_dir, out, "scaling", ["--repeats", "2"])

s = json.loads((rep / "summary.json").read_text())
for k in ("cost", "report", "targets", "targets_check", "render_lp_num_threads", "launcher", "cpus",
          "load_average_start", "load_average_end", "accuracy_ok"):
    check(k in s, f"summary.json has key {k}")
check(s.get("cost") == "cpu", "the suite's default cost is cpu")
check(s.get("render_lp_num_threads") == "0", "dmmr-render ran with LP_NUM_THREADS=0")
check("--bind-to none" in s.get("launcher", "") and "--oversubscribe" in s.get("launcher", ""),
      "the launcher unbound and oversubscribed")
check(s.get("accuracy_ok") is True, "summary.json accuracy_ok is true")
check(s.get("repeats") == 2, "summary.json says each configuration ran twice")
labels = [c["label"] for c in s.get("configurations", [])]
check(labels == [f"render-c{n}" for n in CLIENTS], f"configurations are the plain runs with {CLIENTS} clients")
# the small scale renders points 2..9 of a 12-point walk (path_frames = 12, frames = 8)
check((s.get("frames"), s.get("path_frames"), s.get("path_start")) == (8, 12, 2),
      f"the window of the walk in summary.json: {s.get('frames')}, {s.get('path_frames')}, {s.get('path_start')}")

checks = s.get("targets_check", [])
check(len(checks) == 8, f"eight targets checked ({len(checks)})")
for c in checks:
    check(set(c) == {"target", "met", "detail"} and c["met"] in (True, False, None), f"target entry {c}")
ident = [c for c in checks if "identical" in c.get("target", "")]
check(len(ident) == 1 and ident[0]["met"] is True, "the every-frame-identical target is met")

for sc in s.get("scenes", []):
    name, ref = sc["scene"], sc["reference"]
    for n in CLIENTS:
        r = sc["runs"].get(f"render-c{n}")
        check(r is not None, f"{name}: run with {n} clients")
        if r is None:
            continue
        check(r["accuracy"]["frames"] == ref["frames"] and r["accuracy"]["identical_frames"] == ref["frames"],
              f"{name}/{n}: every frame compared and identical")
        check(len(r["per_client"]) == n, f"{name}/{n}: one entry per client")
        for k in ("derived_efficiency", "derived_speedup_vs_1_client", "client_max_over_mean_median",
                  "derived_cpu_frame_ms_mean", "work_sums", "inflation", "scheduled_frame_ms",
                  "scheduled_efficiency", "scheduled_speedup_vs_1_client", "scheduled_latency_ms"):
            check(r.get(k) is not None, f"{name}/{n}: {k}")
        # the schedule never waits longer than frame-by-frame work does (same costs, frames 1..)
        check(r.get("in_flight") == 3, f"{name}/{n}: the runs' default --in-flight 3 was read")
        check(r["scheduled_frame_ms"] <= r["derived_frame_ms_mean"] * (1 + 1e-9) + 1e-9,
              f"{name}/{n}: scheduled {r['scheduled_frame_ms']} above per-frame {r['derived_frame_ms_mean']}")
        # both runs kept and compared; the figures are the cheaper one's (the lower middle of two)
        reps = r.get("repeats", [])
        check([t["label"] for t in reps] == [f"render-c{n}", f"render-c{n}.r2"], f"{name}/{n}: two runs listed")
        check(sum(t["used"] for t in reps) == 1, f"{name}/{n}: one run used")
        check(all(t["max_differing_pixels"] == 0 for t in reps), f"{name}/{n}: every run exact")
        if len(reps) == 2:
            used = next(t for t in reps if t["used"])
            check(used["cpu_ms"] == min(t["cpu_ms"] for t in reps), f"{name}/{n}: the cheaper of two runs used")
            check(abs(used["cpu_ms"] - r["work_sums"]["cpu_ms"]) < 1e-9, f"{name}/{n}: figures from the run used")
        # the stage threads' kernel time and faults, and the figures by user CPU beside those by CPU
        for k in ("scheduled_user_frame_ms", "client_max_over_mean_user_median", "scheduled_user_efficiency"):
            check(r.get(k) is not None, f"{name}/{n}: {k}")
        for c in r["per_client"]:
            check(0 <= c.get("sys_ms", -1) <= c["vis_cpu_ms"] + c["render_cpu_ms"] + 1.0,
                  f"{name}/{n}: a client's kernel time is part of its CPU time ({c.get('sys_ms')})")
            check(c.get("faults_mean", -1) >= 0, f"{name}/{n}: a client's page faults recorded")
        # per frame, a client's user CPU is at most its CPU (the schedule's mean period is not monotone in
        # the costs: a cheaper frame 0 can lengthen it)
        check(r.get("derived_user_frame_ms_mean", 1e18) <= r["derived_cpu_frame_ms_mean"] * (1 + 1e-9) + 1e-9,
              f"{name}/{n}: the derived frame by user CPU is no longer than by CPU")
        inf = r.get("inflation") or {}
        check(set(WORK) <= set(inf), f"{name}/{n}: inflation of {', '.join(WORK)}")
        if n == 1:
            check(all(inf.get(k) in (1.0, None) for k in WORK), f"{name}/1: inflation 1 against itself")
        # each client reads back its own region: the pixels read back sum to one frame whatever n
        check(inf.get("pixels") is not None and abs(inf["pixels"] - 1.0) < 1e-6, f"{name}/{n}: pixels tile the frame")
        # where the efficiency goes: four factors whose product is the derived efficiency
        if n > 1:
            parts = r.get("efficiency_parts") or {}
            prod = 1.0
            for k in ("one_client", "work", "balance", "server"):
                prod *= parts.get(k, float("nan"))
            check(abs(prod - r["derived_efficiency"]) < 1e-9 * max(1.0, r["derived_efficiency"]),
                  f"{name}/{n}: the efficiency's factors multiply to it ({parts})")
            check(0 < parts.get("balance", 0) <= 1 + 1e-12, f"{name}/{n}: the balance factor is at most 1")
            check(set(r.get("slowest_client") or {}) >= {"cost", "triangles", "pixels"},
                  f"{name}/{n}: the slowest client's figures")
            check((r.get("slowest_client") or {}).get("cost", 0) >= 1 - 1e-12,
                  f"{name}/{n}: the slowest client costs at least the mean")

# every dmmr-render run (repeats included) has its whole-process CPU and page faults
usage = s.get("run_usage") or {}
renders = [k for k in s.get("run_wall_s", {}) if "/render-c" in k]
check(renders and sorted(usage) == sorted(renders), f"usage of every render run: {sorted(usage)}")
check(all(u["user_s"] > 0 and u["minor_faults"] > 0 for u in usage.values()), "each run's CPU and faults counted")
md = (rep / "report.md").read_text()
for heading in ("## Measurement method", "## Scaling", "### Targets (issue 16)", "### Work inflation against 1 client",
                "### Frame time, efficiency, speed-up and balance", "### Repeated runs",
                "### Whole-process CPU of each run", "### Kernel time in the clients' stage threads", "## Summary",
                "## Plots"):
    check(heading in md, f"report.md has '{heading}'")
check(md.index("## Measurement method") < md.index("## Scaling"), "the method comes before the figures")
check("made with 12 control points and the runs render 8 consecutive ones, points 2 to 9" in md,
      "the method names the window of the walk")
for sc in s.get("scenes", []):
    walk = Path(sc.get("walkthrough", ""))
    check(walk.name == f"{sc['scene']}.points2-9.path" and walk.exists(), f"{sc['scene']}: the runs' walk {walk}")
    if walk.exists():
        full = [l.split() for l in walk.with_name(f"{sc['scene']}.path").read_text().splitlines() if l.strip()]
        win = [l.split() for l in walk.read_text().splitlines() if l.strip()]
        check(len(full) == 12 and len(win) == 8 and [w[1:] for w in win] == [f[1:] for f in full[2:10]],
              f"{sc['scene']}: the window is points 2..9 of the 12-point walk")
        check(float(win[0][0]) == 0.0, f"{sc['scene']}: the window's times start at 0")
for words in ("LP_NUM_THREADS=0", "--bind-to none", "oversubscribed", "--cost cpu", "load average",
              "Scheduled frame time", "--in-flight", "**Repeats:**"):
    check(words in md, f"the method says {words!r}")
check(md.count("**met**") + md.count("**not met**") + md.count("**not measured**") == 8, "eight checklist lines")
check("## Speed against error" not in md, "no sweep section without a sweep")
check("| objects tested | objects drawn | triangles drawn |" in md, "the inflation table's header")
if any(c["met"] is False for c in checks):
    check("### Where the time goes" in md and "16 clients, per client and stage" in md,
          "a missed target brings the per-client per-stage breakdown of the largest client count")
    check("4 clients, per client and stage" in md, "and of the 4-client run")
check("### Where the efficiency goes" in md and "| share correlation, 1 frame later |" in md,
      "the report factors the efficiency")
check("FAIL" not in md, "no accuracy FAIL")
png = rep / "plots" / "scaling.png"
check(png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", "plots/scaling.png")
check(not (rep / "plots" / "speed_error.png").exists(), "no speed-against-error plot without a sweep")

print(f"bench_scaling_small: {len(failures)} failed checks; dmmr-bench wall {s.get('wall_s', 0):.1f} s")
sys.exit(1 if failures else 0)
