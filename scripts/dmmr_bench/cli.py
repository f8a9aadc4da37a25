"""dmmr-bench SUITE [--scale small|medium|large] [--out DIR] [--bin DIR]"""
import argparse
import json
import os
import platform
import shlex
import subprocess
import sys
import time
from pathlib import Path

from . import analysis, report
from .runner import Progress, Runner
from .suite import SuiteError, load_suite

ROOT = Path(__file__).resolve().parents[2]


def find_suite(name):
    p = Path(name)
    if p.suffix == ".toml" and p.exists():
        return p
    p = ROOT / "configs" / "bench" / f"{name}.toml"
    if not p.exists():
        known = sorted(x.stem for x in (ROOT / "configs" / "bench").glob("*.toml"))
        sys.exit(f"dmmr-bench: no suite {name!r} (known: {', '.join(known)})")
    return p


def machine():
    cpus = os.cpu_count()
    model = ""
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = ""
    try:
        kb = int(next(l for l in open("/proc/meminfo") if l.startswith("MemTotal")).split()[1])
        mem = f", {kb / 1024 / 1024:.0f} GiB"
    except (OSError, StopIteration, ValueError):
        pass
    return f"{cpus} CPUs ({model}){mem}, {platform.system()} {platform.release()}, no GPU used (llvmpipe)"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="dmmr-bench", description="Walkthrough benchmarks: the paper's tables and "
                                 "figures for dmmr against dmmr-reference, with 1, 2 and 4 clients.")
    ap.add_argument("suite", help="suite name in configs/bench/ (e.g. paper) or a .toml file")
    ap.add_argument("--scale", default="small", help="small (CI, < 2 min), medium, large (default small)")
    ap.add_argument("--out", help="output directory (default out/bench/SUITE-SCALE); scenes there are reused")
    ap.add_argument("--bin", default=os.environ.get("DMMR_BIN"),
                    help="directory of the dmmr tools (default $DMMR_BIN, else build/bin)")
    ap.add_argument("--backend", default="osmesa", choices=["osmesa", "egl"])
    ap.add_argument("--resume", action="store_true", help="reuse runs whose CSVs exist (default: rerun)")
    ap.add_argument("--report-only", action="store_true", help="rebuild the report from existing runs")
    ap.add_argument("--render-option", action="append", default=[], metavar="OPT",
                    help="an extra dmmr-render option for the plain runs (not the threshold sweep), "
                         "repeatable, e.g. --render-option=--stages --render-option=fused")
    ap.add_argument("--cost", choices=["wall", "cpu", "user", "turns"],
                    help="what the derived cluster times are built from: the stages' wall times (wall), "
                         "their threads' CPU time with LP_NUM_THREADS=0 (cpu), that less its kernel part "
                         "(user), or wall times with the GL "
                         "stages taking turns (turns); default: the suite's run.cost, else wall")
    ap.add_argument("--repeats", type=int, metavar="N",
                    help="run each dmmr-render configuration N times and report the run of median summed "
                         "client cost, listing every run (default: the suite's run.repeats, else 1); on a "
                         "shared or small machine single runs of many clients vary by a factor of 1.5")
    a = ap.parse_args(argv)

    suite_path = find_suite(a.suite)
    try:
        suite = load_suite(suite_path)
    except SuiteError as e:
        sys.exit(f"dmmr-bench: {e}")
    if a.scale not in suite.get("scales", {}):
        sys.exit(f"dmmr-bench: suite {a.suite} has no scale {a.scale!r} (has {', '.join(suite.get('scales', {}))})")
    out = Path(a.out or ROOT / "out" / "bench" / f"{suite_path.stem}-{a.scale}").resolve()
    bin_dir = Path(a.bin or ROOT / "build" / "bin").resolve()
    out.mkdir(parents=True, exist_ok=True)
    cost = a.cost or suite.get("run", {}).get("cost", "wall")
    if cost not in analysis.COST_DEFINITIONS:
        sys.exit(f"dmmr-bench: {suite_path}: run.cost {cost!r} is not one of wall, cpu, user, turns")
    analysis.COST = cost
    repeats = a.repeats if a.repeats is not None else int(suite.get("run", {}).get("repeats", 1))
    if repeats < 1:
        sys.exit(f"dmmr-bench: --repeats {repeats}: at least 1")
    runner = Runner(suite, a.scale, out, bin_dir, backend=a.backend, resume=a.resume or a.report_only,
                    render_options=a.render_option, cost=cost, repeats=repeats, report_only=a.report_only)
    cfg = runner.cfg
    scenes = runner.scenes()
    confs = runner.configurations()
    print(f"dmmr-bench: suite {suite_path.stem}, scale {a.scale}: {len(scenes)} scenes x "
          f"(reference{' + osg-occlusion' if runner.osg_baseline else ''} + {len(confs)} dmmr-render runs), "
          f"{cfg.get('width')}x{cfg.get('height')}, "
          f"tools {bin_dir}, output {out} (log: {out / 'bench.log'})", flush=True)
    analysis.LINK_GBPS = float(runner.run_cfg.get("link_gbps", 1.0))
    load_start = os.getloadavg()  # the report says how busy the (shared) machine was
    prev_summary = out / "report" / "summary.json"
    load_earlier = None
    if a.resume and not a.report_only and prev_summary.exists():
        # runs reused from the earlier invocation ran under its load, not this one's
        prev = json.loads(prev_summary.read_text())
        load_earlier = prev.get("load_average_earlier") or [prev.get("load_average_start"), prev.get("load_average_end")]
    t0 = time.monotonic()
    progress = Progress(runner.total_steps())
    results = []
    try:
        for sc in scenes:
            info = runner.run_scene(sc, progress)
            res = analysis.analyse_scene(sc["name"], info, confs, runner.repeats)
            res.update(info)
            res["sweep_clients"] = runner.run_cfg.get("sweep_clients", 1)
            results.append(res)
    except RuntimeError as e:
        print(f"dmmr-bench: {e}", file=sys.stderr)
        return 1
    wall = time.monotonic() - t0
    meta = {
        "suite": suite_path.stem, "scale": a.scale,
        "command": "scripts/dmmr-bench " + " ".join(shlex.quote(x) for x in (argv if argv is not None else sys.argv[1:])),
        "machine": machine(), "width": cfg.get("width"), "height": cfg.get("height"), "backend": a.backend,
        "lp_num_threads": runner.run_cfg.get("lp_num_threads"), "wall_s": wall,
        "resumed": bool(a.resume),  # wall_s then counts only what was rerun
        "configurations": [{"label": l, "clients": n, "options": x} for l, n, x in confs],
        "run_wall_s": runner.timings,
        "run_usage": runner.usage,  # dmmr-render runs: whole-process user/kernel CPU s, minor faults
        "osg": {"tool": "dmmr-osgviewer", "label": "osg-occlusion", "backend": "osmesa",
                "occlusion": "on", "min_vertices": 5000, "visibility_threshold": 0, "query_frame_count": 1,
                **runner.osg},
        "link_gbps": analysis.LINK_GBPS,
        "cost": cost,
        "repeats": runner.repeats,  # runs per dmmr-render configuration; the median-cost one reported
        "report": suite.get("report"),  # "scaling": the scaling section and the targets' checklist
        "targets": suite.get("targets", {}),
        "osg_baseline": runner.osg_baseline,
        "reference_stride": runner.reference_stride(),  # the reference rendered (and compared) every k-th frame
        # the runs' frames: control points path_start.. of a walk made with path_frames (Runner.window_path)
        "frames": cfg.get("frames", 40), "path_frames": runner.path_frames({}), "path_start": runner.path_start({}),
        # how the dmmr-render runs were launched, for the report's measurement method
        "render_lp_num_threads": runner.render_env.get("LP_NUM_THREADS"),
        "launcher": " ".join(runner.render_mpi),  # with its --bind-to choice
        "cpus": os.cpu_count(),
        "load_average_start": [round(x, 2) for x in load_start],
        "load_average_end": [round(x, 2) for x in os.getloadavg()],
        "load_average_earlier": load_earlier,
        "derived_definition": "per frame: the server's cull and divide (plan_cpu_ms with --cost cpu, else "
                              "cull_ms + divide_ms) + max over clients of (the client's own work "
                              "+ bytes_sent at link_gbps); mean over frames 1..; a client's work is its "
                              + analysis.COST_DEFINITIONS[cost],
    }
    try:
        meta["git"] = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                                     capture_output=True, text=True).stdout.strip()
    except OSError:
        pass
    old = out / "report" / "summary.json"
    if a.report_only and old.exists():
        # a rebuilt report describes the runs it reads: keep when, how long and on how busy a machine
        # they ran, not this rebuild's
        prev = json.loads(old.read_text())
        for k in ("command", "machine", "wall_s", "resumed", "run_wall_s", "run_usage", "load_average_start",
                  "load_average_end",
                  "load_average_earlier", "git"):
            if k in prev:
                meta[k] = prev[k]
    frames = max(len(s["reference"]["frame_ms_series"]) for s in results)
    window = max(1, min(10, frames // 8))
    ok = report.write(out / "report", meta, results, window)
    print(f"dmmr-bench: done in {wall:.0f} s; report {out / 'report' / 'report.md'}"
          f"{'' if ok else ' -- ACCURACY FAILED (a conservative run differs from the reference)'}", flush=True)
    return 0 if ok else 2
