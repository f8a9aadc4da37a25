"""The report: summary.json, tables as Markdown, plots as PNG, per-frame CSVs."""
import json
import math
import re
import shutil
from pathlib import Path


def f(x, fmt="{:.1f}"):
    if x is None or x == "inf":
        return "—" if x is None else "inf"
    if isinstance(x, float) and math.isnan(x):
        return "—"
    return fmt.format(x)


def pct(x):
    return "—" if x is None else f"{100 * x:.1f}%"


def ratio(x):
    if x is None:
        return "—"
    return f"{x:.2f}x" + (" (faster)" if x >= 1 else " (slower)")


OSG_NAME = "osg-occlusion (osgViewer + OcclusionQueryNode)"


def osg_ms(s):
    return s["osg"]["frame_ms_mean"] if s.get("osg") else None


def plain_runs(res):
    return [(k, r) for k, r in res["runs"].items() if r.get("plain", not r["options"])]


def per_client(r, key, fmt="{:.1f}"):
    return " / ".join(f(c[key], fmt) for c in r["per_client"])


def table_for_clients(scenes, n):
    """A Table 1-3 style table: rows are stages, columns scenes, for n clients."""
    cols = [(s, s["runs"].get(f"render-c{n}")) for s in scenes]
    cols = [(s, r) for s, r in cols if r]
    if not cols:
        return ""
    head = "| | " + " | ".join(f"{s['scene']} ({s['counts'].get('objects', 0):,} objects, "
                                  f"{s['counts'].get('triangles', 0) / 1e6:.2f}M triangles)" for s, _ in cols) + " |"
    lines = [f"#### dmmr with {n} client{'s' if n > 1 else ''} (means over frames 1.., ms unless said; "
             f"per-client figures as c1 / c2 / ...)", "", head, "|---" * (len(cols) + 1) + "|"]

    def row(label, fn):
        lines.append(f"| {label} | " + " | ".join(fn(s, r) for s, r in cols) + " |")

    row("FPS and frame time, measured (shared 2 cores)",
        lambda s, r: f"{f(r['fps_min'])}-{f(r['fps_max'])} fps / {f(r['frame_ms_mean'])} ms")
    row("frame time, median measured / reference", lambda s, r: f"{f(r['frame_ms_median'])} / "
        f"{f(s['reference']['frame_ms_median'])} ms")
    row("frame time, dmmr-reference (same run)", lambda s, r: f"{f(s['reference']['frame_ms_mean'])} ms")
    row("measured vs reference", lambda s, r: ratio(r["speedup_vs_reference"]))
    row("frame time, osg-occlusion (same run)", lambda s, r: f"{f(osg_ms(s))} ms")
    row("measured vs osg-occlusion", lambda s, r: ratio(r.get("speedup_vs_osg")))
    row("**derived** cluster frame time (1 machine per client)", lambda s, r: f"{f(r['derived_frame_ms_mean'])} ms")
    row("**derived** vs reference", lambda s, r: ratio(r["derived_speedup_vs_reference"]))
    row("**derived** vs osg-occlusion", lambda s, r: ratio(r.get("derived_speedup_vs_osg")))
    row("**derived**, stages overlapped", lambda s, r: f"{f(r['derived_pipelined_ms_mean'])} ms")
    row("**derived** efficiency tau_1 / (S tau_S)", lambda s, r: f(r.get("derived_efficiency"), "{:.2f}"))
    row("server: frustum culling", lambda s, r: f(r["server"]["cull_ms"], "{:.2f}"))
    row("server: frustum division", lambda s, r: f(r["server"]["divide_ms"], "{:.2f}"))
    row("server: send jobs", lambda s, r: f(r["server"]["send_ms"], "{:.2f}"))
    row("server: assemble sub-frames", lambda s, r: f(r["server"]["assemble_ms"], "{:.2f}"))
    row("client: visibility, prepare (occluders, tests)", lambda s, r: per_client(r, "prepare_ms"))
    row("client: visibility, retrieve (depth readback or query results)", lambda s, r: per_client(r, "retrieve_ms"))
    row("client: pass on to the render stage", lambda s, r: per_client(r, "pass_ms"))
    row("client: load geometry", lambda s, r: per_client(r, "load_ms"))
    row("client: render", lambda s, r: per_client(r, "render_ms"))
    row("client: read back + compress", lambda s, r: " / ".join(
        f(c["readback_ms"] + c["compress_ms"]) for c in r["per_client"]))
    row("client: send to server", lambda s, r: per_client(r, "send_ms"))
    row("client: own work (prepare+retrieve+load+render+readback+compress)", lambda s, r: per_client(r, "work_ms"))
    row("client: CPU time, visibility / render stage thread", lambda s, r: " / ".join(
        f"{f(c['vis_cpu_ms'])}:{f(c['render_cpu_ms'])}" for c in r["per_client"]))
    row("client: cost used for the derived time", lambda s, r: per_client(r, "cost_ms"))
    row("derived from wall / from CPU time", lambda s, r: f"{f(r['derived_wall_frame_ms_mean'])} / "
        f"{f(r.get('derived_cpu_frame_ms_mean'))} ms")
    row("client time max/mean (median over frames)", lambda s, r: f(r.get("client_max_over_mean_median"), "{:.2f}"))
    row("client: transfer of its sub-frame at the nominal link (derived)", lambda s, r: per_client(r, "transfer_ms", "{:.2f}"))
    row("triangles drawn per client", lambda s, r: per_client(r, "triangles_mean", "{:,.0f}"))
    row("triangles drawn, all / reference", lambda s, r: f"{r['triangles_drawn_mean']:,.0f} / "
        f"{s['reference']['triangles_mean']:,.0f}")
    row("objects queried / visible per client", lambda s, r: " / ".join(
        f"{c['queried_mean']:,.0f}:{c['visible_mean']:,.0f}" for c in r["per_client"]))
    row("GPU cache hit rate (RAM)", lambda s, r: f"{pct(r['gpu_hit_rate'])} ({pct(r['ram_hit_rate'])})")
    row("bytes sent per frame (all clients)", lambda s, r: f"{r['bytes_sent_mean'] / 1024:,.1f} KiB")
    row("differing pixels (worst frame) / min PSNR", lambda s, r: f"{r['accuracy']['max_differing_pixels']} / "
        f"{f(r['accuracy']['min_psnr_db'])}")
    return "\n".join(lines) + "\n"


def summary_table(scenes):
    lines = ["| scene | configuration | frame ms (measured mean) | median | vs reference (means) | vs osg-occlusion (means) | "
             "derived ms | derived vs reference | derived vs osg-occlusion | "
             "derived efficiency | triangles drawn | differing pixels (worst) | min PSNR dB | accuracy |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in scenes:
        ref, osg = s["reference"], s.get("osg")
        lines.append(f"| {s['scene']} | dmmr-reference (brute force) | {f(ref['frame_ms_mean'])} | {f(ref['frame_ms_median'])} | 1.00x | "
                     f"{ratio(osg['frame_ms_mean'] / ref['frame_ms_mean']) if osg and ref['frame_ms_mean'] > 0 else '—'} | | | | | "
                     f"{ref['triangles_mean']:,.0f} | reference | reference | |")
        if osg:
            lines.append(f"| {s['scene']} | {OSG_NAME} | {f(osg['frame_ms_mean'])} | {f(osg['frame_ms_median'])} | "
                         f"{ratio(osg['speedup_vs_reference'])} | 1.00x | | | | | {osg['triangles_mean']:,.0f} | "
                         f"not compared (OSG's shading) | | |")
        for k, r in s["runs"].items():
            conf = f"{r['clients']} client{'s' if r['clients'] > 1 else ''}"
            if r["options"]:
                conf += " " + " ".join(r["options"])
            lines.append(f"| {s['scene']} | {conf} | {f(r['frame_ms_mean'])} | {f(r['frame_ms_median'])} | {ratio(r['speedup_vs_reference'])} | "
                         f"{ratio(r.get('speedup_vs_osg'))} | "
                         f"{f(r['derived_frame_ms_mean'])} | {ratio(r['derived_speedup_vs_reference'])} | "
                         f"{ratio(r.get('derived_speedup_vs_osg'))} | "
                         f"{f(r.get('derived_efficiency'), '{:.2f}')} | {r['triangles_drawn_mean']:,.0f} | "
                         f"{r['accuracy']['max_differing_pixels']} | {f(r['accuracy']['min_psnr_db'])} | "
                         f"{'ok' if r['accuracy_ok'] else 'FAIL'}{'' if r['conservative'] else ' (approximate)'} |")
    return "\n".join(lines) + "\n"


def sweep_table(scenes):
    lines = ["| scene | query threshold | clients | frame ms | derived ms | triangles drawn | mean PSNR dB | "
             "min PSNR dB | differing pixels (worst frame) |", "|---|---|---|---|---|---|---|---|---|"]
    for s in scenes:
        for r in sorted((r for r in s["runs"].values() if r["clients"] == s.get("sweep_clients", 1)),
                        key=lambda r: r["query_threshold"]):
            a = r["accuracy"]
            lines.append(f"| {s['scene']} | {r['query_threshold']} | {r['clients']} | {f(r['frame_ms_mean'])} | "
                         f"{f(r['derived_frame_ms_mean'])} | {r['triangles_drawn_mean']:,.0f} | "
                         f"{f(a['mean_psnr_db'])} | {f(a['min_psnr_db'])} | {a['max_differing_pixels']} |")
    return "\n".join(lines) + "\n"


def verdict(scenes):
    out = []
    for s in scenes:
        parts = []
        for k, r in plain_runs(s):
            m, d = r["speedup_vs_reference"], r["derived_speedup_vs_reference"]
            parts.append(f"{r['clients']} client{'s' if r['clients'] > 1 else ''}: measured {ratio(m)}, "
                         f"derived {ratio(d)}")
        out.append(f"- **{s['scene']}** against dmmr-reference: " + "; ".join(parts) + ".")
        osg = s.get("osg")
        if osg:
            parts = []
            for k, r in plain_runs(s):
                parts.append(f"{r['clients']} client{'s' if r['clients'] > 1 else ''}: measured "
                             f"{ratio(r.get('speedup_vs_osg'))}, derived {ratio(r.get('derived_speedup_vs_osg'))}")
            out.append(f"  Against osg-occlusion ({f(osg['frame_ms_mean'])} ms per frame, "
                       f"{ratio(osg['speedup_vs_reference'])} than dmmr-reference): " + "; ".join(parts) + ".")
    return "\n".join(out) + "\n"


# --- the scaling suite (issue 16) ----------------------------------------------------
def sweep_runs(s):
    return [r for r in s["runs"].values() if not r["plain"]]


def scaling_runs(s):
    """The plain runs of a scene by client count."""
    return sorted((r for _, r in plain_runs(s)), key=lambda r: r["clients"])


def method_section(meta):
    cost = meta.get("cost", "wall")
    n_max = max((c["clients"] for c in meta.get("configurations", [])), default=1)
    lp = meta.get("render_lp_num_threads")
    la0, la1 = meta.get("load_average_start"), meta.get("load_average_end")
    load = (f"load average (1, 5, 15 min) {', '.join(f'{x:.2f}' for x in la0)} at the start and "
            f"{', '.join(f'{x:.2f}' for x in la1)} at the end" if la0 and la1 else "load average not recorded")
    earlier = meta.get("load_average_earlier")
    if earlier and all(earlier):
        load += (" of this (resumed) invocation; the runs it reused ran in an earlier one: load average "
                 f"{', '.join(f'{x:.2f}' for x in earlier[0])} at its start and "
                 f"{', '.join(f'{x:.2f}' for x in earlier[1])} at its end")
    cost_line = {
        "cpu": "a client's cost in a frame is the CPU time of its two stage threads (`cN_vis_cpu_ms + "
               "cN_render_cpu_ms`, `CLOCK_THREAD_CPUTIME_ID`). CPU time does not count time spent waiting for a "
               "core, so it holds with more processes than cores; what sharing still changes (caches, memory "
               "bandwidth) is not removed.",
        "wall": "a client's cost in a frame is the wall time of its working stages (prepare, retrieve, load, "
                "render, read back, compress), waiting for a core included: with more processes than cores this "
                "measures contention as much as work.",
        "user": "a client's cost in a frame is the user CPU time of its two stage threads (`cN_vis_cpu_ms + "
                "cN_render_cpu_ms` less their kernel part `cN_vis_sys_ms + cN_render_sys_ms`, from "
                "`getrusage(RUSAGE_THREAD)`): CPU time free of waiting for a core, without the kernel's page-fault "
                "time, whose cost on a shared virtual machine depends on the host.",
        "turns": "a client's cost in a frame is the wall time of its working stages, taken with `--stage-turns` "
                 "(one GL stage at a time on the machine).",
    }[cost]
    return "\n".join([
        "## Measurement method", "",
        f"- **Cost (`--cost {cost}`):** {cost_line}",
        f"- **LP_NUM_THREADS:** dmmr-render runs with `LP_NUM_THREADS={lp if lp is not None else 'unset'}`"
        + (" (llvmpipe rasterises on the calling stage thread, so the stage threads' CPU time is the whole GL "
           "cost)" if lp == "0" else "")
        + f"; dmmr-reference{' and dmmr-osgviewer' if meta.get('osg_baseline', True) else ''} with "
          f"`LP_NUM_THREADS={meta.get('lp_num_threads') or 'unset (llvmpipe default)'}`.",
        f"- **Launch and binding:** `{meta.get('launcher', meta.get('mpirun', 'mpirun --bind-to none'))} -np N+1 dmmr-render ...`: rank 0 is the "
        f"server, ranks 1..N the clients, no process bound to a core. With up to {n_max} clients that is "
        f"{n_max + 1} processes (each client with two GL stage threads) on {meta.get('cpus', '?')} cores: "
        "**oversubscribed**, so measured wall times are not cluster times.",
        "- **Derived frame time:** per frame, the server's culling and division plus, for the slowest client, its "
        f"cost plus the transfer of its compressed sub-frame over a nominal {meta.get('link_gbps', 1.0):g} Gbit/s "
        "link (one machine per client, no overlap between frames; hand-over waits left out); the mean over frames "
        "1.. (frame 0 fills the caches). With `--cost cpu` the server's culling and division are the CPU time of "
        "the threads that did them (`plan_cpu_ms`; CSVs without it fall back to the wall times "
        "`cull_ms + divide_ms`, which with more processes than cores include waiting for a core); otherwise "
        "their wall times. "
        "**Efficiency** is tau_1 / (S tau_S) and **speed-up** tau_1 / tau_S, "
        "both over derived times of the same scene. **max/mean** is, per frame, the slowest client's cost over "
        "the mean client cost, median over frames.",
        "- **Scheduled frame time:** the same per-frame costs put through dmmr's own schedule on such a "
        "cluster: the server plans frame f once frame f - N is assembled (N = `--in-flight`, 3 by default; "
        "`Assembler::waitForRoom`), one plan after another; each client works through its jobs in order, "
        "starting one when its previous job and the frame's plan are done, busy until its sub-frame has left; a "
        "frame is assembled when its last sub-frame is in (assembly and PNG writing, on the server's other "
        "thread, left out as above). The scheduled frame time is the mean time between assemblies over frames "
        "1..; the latency, the mean time from a frame's planning to its assembly. A client that is slowest on "
        "one frame and quick on the next is not waited for twice, so this is at most the per-frame figure; "
        "with `--in-flight 1` the two are the same (`tests/bench/test_schedule.py`).",
        "- **Work inflation:** the sum over clients of each figure (means per frame over frames 1..) divided by "
        "the 1-client run's: objects queried/tested (`cN_queried`), objects drawn (`cN_visible`), triangles "
        "drawn (`cN_triangles`), occluders drawn (`cN_occluders`, objects: the CSV has no occluder triangle "
        "count), pixels read back (`cN_bytes_raw / 3`) and client CPU time (`cN_vis_cpu_ms + cN_render_cpu_ms`).",
        f"- **Machine while measuring:** {load}, on {meta.get('cpus', '?')} cores "
        "(other work may have shared the machine).",
        *([f"- **Repeats:** each dmmr-render configuration ran {meta['repeats']} times, in rounds (each round "
           "runs every configuration once, so that a slow spell of a shared machine falls on several "
           "configurations, not on all of one's runs); every figure is that of the run with the median "
           "summed client cost (the lower middle one of an "
           "even count), every run is compared with the reference, and the scaling section lists each run's "
           "cost and frame times."] if int(meta.get("repeats", 1) or 1) > 1 else []),
        *walk_lines(meta), accuracy_line(meta), ""])


def walk_lines(meta):
    """The method's line on a window of a longer walk (Runner.window_path), if the scale renders one."""
    frames, p = int(meta.get("frames") or 0), int(meta.get("path_frames") or 0)
    if not frames or p <= frames:
        return []
    start = int(meta.get("path_start") or 0)
    return [f"- **Walkthrough:** each scene's fly-through is made with {p} control points and the runs render "
            f"{frames} consecutive ones, points {start} to {start + frames - 1} (renumbered as frames 0 to "
            f"{frames - 1}), so that the camera moves as far a frame as along the whole {p}-point walk: "
            f"{p / frames:.1f} times less than if the same path were crossed in {frames} frames. Frame-to-frame "
            "coherence is what the division's feedback (objects drawn lately, fitted costs) relies on."]


def accuracy_line(meta):
    k = int(meta.get("reference_stride", 1) or 1)
    if k == 1:
        return ("- **Accuracy:** every dmmr-render frame is compared with dmmr-reference's frame of the same index "
                "(same walkthrough, same frame count).")
    return (f"- **Accuracy:** brute force is slow at this scale, so dmmr-reference renders one control point in {k} "
            f"of the walkthrough (frames 0, {k}, {2 * k}, ...: the same cameras) and each dmmr-render run's "
            "frames of those indices are compared with it, frame for frame; \"identical frames\" counts those. "
            "The \"vs reference\" ratios therefore compare means over different frames of the same path.")


def check_targets(meta, scenes):
    """The issue's targets, each met or not from the figures: [{target, met, detail}]."""
    t = meta.get("targets") or {}
    out = []

    def run_of(s, n):
        return next((r for r in scaling_runs(s) if r["clients"] == n), None)

    def at_least(what, key, n, goal, unit=""):
        vals = [(s["scene"], (run_of(s, n) or {}).get(key)) for s in scenes]
        have = [(sc, v) for sc, v in vals if v is not None]
        out.append({"target": what, "met": (len(have) == len(vals) and all(v >= goal for _, v in have))
                    if have else None,
                    "detail": f"met on {sum(1 for _, v in have if v >= goal)} of {len(vals)} scenes: "
                              + ", ".join(f"{sc} {f(v, '{:.3f}')}{unit}" for sc, v in vals)})

    # Each frame-time target twice: by the per-frame derivation (no overlap
    # between frames), and by the run's schedule replayed (frames in flight).
    for label, prefix in (("derived, per frame", "derived"), ("derived, scheduled", "scheduled")):
        for n, goal in sorted(((int(k), v) for k, v in t.get("efficiency", {}).items())):
            at_least(f"efficiency at least {goal:g} with {n} clients ({label}), every scene",
                     f"{prefix}_efficiency", n, goal)
        if "speedup_4" in t:
            at_least(f"4 clients at least {t['speedup_4']:g}x faster than 1 ({label}), every scene",
                     f"{prefix}_speedup_vs_1_client", 4, t["speedup_4"], "x")
    if "max_over_mean" in t:
        goal = t["max_over_mean"]
        worst = []
        for s in scenes:
            multi = [r for r in scaling_runs(s) if r["clients"] > 1]
            if multi:
                w = max(multi, key=lambda r: r["client_max_over_mean_median"])
                worst.append((s["scene"], w["clients"], w["client_max_over_mean_median"]))
        out.append({"target": f"median max/mean client time at most {goal:g} (every run with 2 or more clients)",
                    "met": all(v <= goal for _, _, v in worst) if worst else None,
                    "detail": "worst per scene: " + ", ".join(f"{sc} {v:.2f} ({n} clients)" for sc, n, v in worst)})
    frames = identical = 0
    for s in scenes:
        for r in s["runs"].values():
            if r["conservative"]:
                frames += r["accuracy"]["frames"]
                identical += r["accuracy"]["identical_frames"]
    counts_ok = all(r["accuracy"]["frames"] == s["reference"]["frames"]
                    for s in scenes for r in s["runs"].values() if r["conservative"])
    out.append({"target": "every conservative frame identical to the reference",
                "met": frames > 0 and identical == frames and counts_ok,
                "detail": f"{identical} of {frames} frames identical"
                          + ("" if counts_ok else "; some run has fewer frames compared than the reference")})
    return out


def targets_checklist(checks):
    mark = {True: "[x] **met**", False: "[ ] **not met**", None: "[ ] **not measured**"}
    return "\n".join(f"- {mark[c['met']]}: {c['target']} ({c['detail']})" for c in checks) + "\n"


def scaling_table(scenes):
    lines = ["| scene | clients | derived ms | efficiency | speed-up vs 1 client | max/mean client (median) | "
             "scheduled ms | efficiency (scheduled) | speed-up (scheduled) | latency (scheduled) ms | "
             "derived from wall (for comparison) | measured frame ms (oversubscribed) | identical frames |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in scenes:
        for r in scaling_runs(s):
            a = r["accuracy"]
            lines.append(f"| {s['scene']} | {r['clients']} | {f(r['derived_frame_ms_mean'])} | "
                         f"{f(r.get('derived_efficiency'), '{:.2f}')} | "
                         f"{f(r.get('derived_speedup_vs_1_client'), '{:.2f}')}x | "
                         f"{f(r['client_max_over_mean_median'], '{:.2f}')} | "
                         f"{f(r.get('scheduled_frame_ms'))} | {f(r.get('scheduled_efficiency'), '{:.2f}')} | "
                         f"{f(r.get('scheduled_speedup_vs_1_client'), '{:.2f}')}x | "
                         f"{f(r.get('scheduled_latency_ms'))} | {f(r['derived_wall_frame_ms_mean'])} | "
                         f"{f(r['frame_ms_mean'])} | {a['identical_frames']}/{a['frames']} |")
    return "\n".join(lines) + "\n"


def repeats_table(scenes):
    """Each repeated run's summed client cost and frame times; "used" marks the run the report's figures are."""
    lines = ["| scene | clients | run | client CPU ms (summed) | derived ms | scheduled ms | worst differing pixels |"
             " used |", "|---|---|---|---|---|---|---|---|"]
    for s in scenes:
        for r in scaling_runs(s):
            for t in r.get("repeats", []):
                lines.append(f"| {s['scene']} | {r['clients']} | {t['label']} | {f(t['cpu_ms'])} | "
                             f"{f(t['derived_frame_ms'])} | {f(t['scheduled_frame_ms'])} | "
                             f"{t['max_differing_pixels']} | {'yes' if t['used'] else ''} |")
    return "\n".join(lines) + "\n"


def usage_table(meta):
    """Each dmmr-render run's whole-process CPU (every rank and thread, start-up included) and minor page
    faults, from meta["run_usage"] (runs reused by --resume have none)."""
    usage, wall = meta.get("run_usage") or {}, meta.get("run_wall_s") or {}
    lines = ["| run | wall s | user CPU s | kernel CPU s | kernel share | minor page faults |",
             "|---|---|---|---|---|---|"]
    def natural(key):  # render-c2 before render-c16
        return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", key)]

    for key in sorted(usage, key=natural):
        u = usage[key]
        cpu = u["user_s"] + u["sys_s"]
        lines.append(f"| {key} | {f(wall.get(key))} | {u['user_s']:.1f} | {u['sys_s']:.1f} | "
                     f"{pct(u['sys_s'] / cpu) if cpu > 0 else '-'} | {u['minor_faults']:,} |")
    return "\n".join(lines) + "\n"


def kernel_table(scenes):
    """Per run: the clients' stage-thread CPU summed, its kernel part and page faults, and the scaling figures
    by CPU time beside those by user CPU time (runs whose CSVs have no kernel time are left out)."""
    lines = ["| scene | clients | client CPU ms | of it kernel ms | kernel share | page faults | "
             "scheduled efficiency (CPU) | (user CPU) | max/mean client (CPU) | (user CPU) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    shown = False
    for s in scenes:
        for r in scaling_runs(s):
            if "scheduled_user_frame_ms" not in r:
                continue
            shown = True
            cpu = sum(c["vis_cpu_ms"] + c["render_cpu_ms"] for c in r["per_client"])
            sys_ms = sum(c["sys_ms"] for c in r["per_client"])
            faults = sum(c["faults_mean"] for c in r["per_client"])
            lines.append(f"| {s['scene']} | {r['clients']} | {f(cpu)} | {f(sys_ms)} | "
                         f"{pct(sys_ms / cpu) if cpu > 0 else '-'} | {faults:,.0f} | "
                         f"{f(r.get('scheduled_efficiency'), '{:.2f}')} | "
                         f"{f(r.get('scheduled_user_efficiency'), '{:.2f}')} | "
                         f"{f(r['client_max_over_mean_median'], '{:.2f}')} | "
                         f"{f(r.get('client_max_over_mean_user_median'), '{:.2f}')} |")
    return "\n".join(lines) + "\n" if shown else ""


def inflation_table(scenes):
    from .analysis import WORK_SUMS
    keys = list(WORK_SUMS)
    lines = ["| scene | clients | " + " | ".join(WORK_SUMS[k][0] for k in keys) + " |",
             "|---|---|" + "---|" * len(keys)]
    fmt = {"cpu_ms": "{:,.1f}"}
    for s in scenes:
        for r in scaling_runs(s):
            inf = r.get("inflation") or {}
            cells = [f"{f(r['work_sums'][k], fmt.get(k, '{:,.0f}'))} ({f(inf.get(k), '{:.2f}')}x)" for k in keys]
            lines.append(f"| {s['scene']} | {r['clients']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def efficiency_table(scenes):
    """Each run's derived efficiency as the product of analysis.efficiency_parts,
    then what the frames' slowest client did against their mean client and
    how a client's share repeats later (analysis.slowest_client_profile,
    share_correlation)."""
    from .analysis import SLOWEST_FIGURES
    keys = list(SLOWEST_FIGURES)
    lines = ["| scene | clients | efficiency | = 1-client frame / its work | x 1 / inflation | x mean / slowest "
             "client | x slowest client / frame | slowest / mean client: cost (the max/mean above) | " +
             " | ".join(SLOWEST_FIGURES[k][0] for k in keys) +
             " | share correlation, 1 frame later | in-flight frames later |",
             "|---|---|" + "---|" * (6 + len(keys) + 2)]
    shown = False
    for s in scenes:
        for r in scaling_runs(s):
            p, sl, corr = r.get("efficiency_parts"), r.get("slowest_client"), r.get("share_correlation")
            if not p or not sl:
                continue
            shown = True
            # JSON turns the lags into strings; analysis gives ints
            corr = {int(k): v for k, v in (corr or {}).items()}
            lag = r.get("in_flight", 3)
            lines.append(f"| {s['scene']} | {r['clients']} | {p['efficiency']:.2f} | {p['one_client']:.2f} | "
                         f"{p['work']:.2f} | {p['balance']:.2f} | {p['server']:.2f} | "
                         f"{f(sl.get('cost'), '{:.2f}')} | " +
                         " | ".join(f(sl.get(k), "{:.2f}") for k in keys) +
                         f" | {f(corr.get(1), '{:.2f}')} | {f(corr.get(lag), '{:.2f}')} ({lag}) |")
    return "\n".join(lines) + "\n" if shown else ""


BREAKDOWN_WALL = ["prepare_ms", "retrieve_ms", "pass_ms", "load_ms", "render_ms", "readback_ms", "compress_ms",
                  "send_ms"]


def breakdown_table(s, clients=None):
    """Client by client, stage by stage, for the scene's run with `clients`
    clients (default: its largest client count), the 1-client run's client
    first. Empty if the scene has no such run."""
    runs = scaling_runs(s)
    if not runs:
        return ""
    big = runs[-1] if clients is None else next((r for r in runs if r["clients"] == clients), None)
    one = runs[0]
    if big is None:
        return ""
    head = ("| run | client | " + " | ".join(x[:-3] for x in BREAKDOWN_WALL) +
            " | vis CPU | render CPU | cost used | objects tested | objects drawn | triangles | pixels read back |")
    lines = [f"#### {s['scene']}: {big['clients']} clients, per client and stage (ms per frame, means over frames "
             f"1..; stage columns are wall times, waiting included; CPU columns are the stage threads' CPU time)",
             "", head, "|---|---|" + "---|" * (len(BREAKDOWN_WALL) + 7)]
    rows = [("1 client", 1, one["per_client"][0])] if one is not big else []
    rows += [(f"{big['clients']} clients", k + 1, c) for k, c in enumerate(big["per_client"])]
    for label, k, c in rows:
        lines.append(f"| {label} | c{k} | " + " | ".join(f(c[x]) for x in BREAKDOWN_WALL) +
                     f" | {f(c['vis_cpu_ms'])} | {f(c['render_cpu_ms'])} | {f(c['cost_ms'])} | "
                     f"{c['queried_mean']:,.0f} | {c['visible_mean']:,.0f} | {c['triangles_mean']:,.0f} | "
                     f"{c['bytes_raw_mean'] / 3:,.0f} |")
    return "\n".join(lines) + "\n"


def scaling_section(meta, scenes, checks):
    md = ["## Scaling", "",
          f"### Targets (issue 16), from the figures below (scale `{meta['scale']}`)", "",
          targets_checklist(checks),
          "### Frame time, efficiency, speed-up and balance", "",
          f"Derived times by `--cost {meta.get('cost', 'wall')}`; efficiency tau_1 / (S tau_S) and speed-up "
          "against the 1-client run of the same scene.", "", scaling_table(scenes),
          "### Work inflation against 1 client", "",
          "Each cell: the run's figure summed over its clients, per frame (mean over frames 1..), and in "
          "brackets that sum over the 1-client run's. Above 1, the clients together do more work than one "
          "client did alone (objects straddling regions tested and drawn by each client whose region they "
          "touch, occluders drawn by every client, per-client fixed costs).", "", inflation_table(scenes)]
    eff = efficiency_table(scenes)
    if eff:
        md += ["### Where the efficiency goes", "",
               "The derived efficiency tau_1 / (S tau_S) is the product of four factors (means over frames "
               "1..): the 1-client frame over its client's work (above 1: the server's plan and the transfer "
               "on top); 1 / the inflation of the clients' summed work; the mean over frames of the mean "
               "client's work over the mean over frames of the slowest client's (not the median max/mean of "
               "the table above); and the slowest client's work over the derived frame (the server's plan "
               "and the transfer on top). "
               "Then, per frame, the slowest client's figures over the frame's mean client's (median over "
               "frames): where its counts are as high as its cost, its region held more work than the "
               "division planned; where they are near 1, it did as much as the others, only slower. Last, "
               "the correlation of a client's share of a frame's work with its share 1 frame and in-flight "
               "frames later. The server plans with feedback that old, and the shares are measured after it "
               "acted on it: near 0, what its correction leaves is not predictable from shares that old.",
               "", eff]
    if int(meta.get("repeats", 1) or 1) > 1:
        md += ["### Repeated runs", "",
               f"Each configuration ran {meta['repeats']} times; the figures above are those of the run of median "
               "summed client cost (used).", "", repeats_table(scenes)]
    if meta.get("run_usage"):
        md += ["### Whole-process CPU of each run", "",
               "User and kernel CPU seconds of mpirun and every rank with all their threads (getrusage of the "
               "benchmark's children), start-up included, and the minor page faults they took. The clients' "
               "figures above are their stage threads' CPU time, which counts a page fault's kernel time too: "
               "on a shared virtual machine that cost varies from run to run, and a run whose kernel share stands "
               "out was slowed by it.", "", usage_table(meta)]
    kernel = kernel_table(scenes)
    if kernel:
        md += ["### Kernel time in the clients' stage threads", "",
               "Per frame (means over frames 1..), summed over the clients: their stage threads' CPU time, the "
               "kernel's part of it and the minor page faults they took (`getrusage(RUSAGE_THREAD)`), then the "
               "scheduled efficiency and per-frame balance by CPU time (the figures above) and by user CPU time "
               "(`--cost user`: the kernel's part left out). On a shared virtual machine a page fault's cost "
               "depends on the host; where the two columns part, the kernel's time moved the figure. The kernel part is "
               "Linux's split of a thread's exact run time by its sampled user and kernel ticks (every 4 ms at "
               "250 Hz): over runs of frames of a few milliseconds it is coarse.", "", kernel]
    if any(c["met"] is False for c in checks):
        md += ["### Where the time goes (a target is not met)", "",
               "The 1-client run's client first, then each client of the 4-client run (where the suite has "
               "one) and of the largest run. With fused stages (the default) the visibility test runs on the "
               "render thread, so its CPU time is in render CPU and vis "
               "CPU is 0; `pass` and `send` are hand-over waits, and under oversubscription every wall column "
               "includes waiting for a core.", ""]
        for s in scenes:
            counts = sorted({r["clients"] for r in scaling_runs(s)})
            for n in ([4] if 4 in counts and counts[-1] != 4 else []) + [None]:
                md += [breakdown_table(s, n), ""]
    return "\n".join(md) + "\n"


# --- plots ---------------------------------------------------------------------------
def smooth(xs, w):
    if w <= 1 or len(xs) < w:
        return list(xs)
    return [sum(xs[max(0, i - w + 1):i + 1]) / len(xs[max(0, i - w + 1):i + 1]) for i in range(len(xs))]


def plots(scenes, dest, window):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    dest.mkdir(parents=True, exist_ok=True)
    made = []

    def save(fig, name):
        fig.tight_layout()
        fig.savefig(dest / name, dpi=90)
        plt.close(fig)
        made.append(name)

    # Figures 8 and 10: frame time along the path, per configuration, one panel per scene
    fig, axes = plt.subplots(len(scenes), 1, figsize=(8, 2.8 * len(scenes)), squeeze=False)
    for ax, s in zip(axes[:, 0], scenes):
        ax.plot(smooth(s["reference"]["frame_ms_series"], window), "k-", label="dmmr-reference")
        if s.get("osg"):
            ax.plot(smooth(s["osg"]["frame_ms_series"], window), "k:", label="osg-occlusion")
        for k, r in plain_runs(s):
            line, = ax.plot(smooth(r["series"]["frame_ms"], window), label=f"{r['clients']} cl. measured")
            ax.plot(smooth(r["series"]["derived_frame_ms"], window), "--", color=line.get_color(),
                    label=f"{r['clients']} cl. derived")
        ax.set_yscale("log")
        ax.set_title(f"{s['scene']}: frame time (mean of {window} frames; log scale)")
        ax.set_xlabel("frame")
        ax.set_ylabel("ms")
        ax.legend(fontsize=7, ncol=2)
    save(fig, "frame_time.png")

    # Figures 12 and 13: division time along the path, per scene, most clients
    fig, ax = plt.subplots(figsize=(8, 3.5))
    for s in scenes:
        runs = plain_runs(s)
        if runs:
            k, r = max(runs, key=lambda kr: kr[1]["clients"])
            ax.plot(smooth(r["series"]["divide_ms"], window), label=f"{s['scene']} ({r['clients']} clients)")
    ax.set_title(f"Load-balanced frustum division (mean of {window} frames)")
    ax.set_xlabel("frame")
    ax.set_ylabel("ms")
    ax.legend(fontsize=8)
    save(fig, "division_time.png")

    # Figure 11: occlusion-query preparation per client, most clients, one panel per scene
    fig, axes = plt.subplots(len(scenes), 1, figsize=(8, 2.5 * len(scenes)), squeeze=False)
    for ax, s in zip(axes[:, 0], scenes):
        runs = plain_runs(s)
        if not runs:
            continue
        k, r = max(runs, key=lambda kr: kr[1]["clients"])
        for i, series in enumerate(r["series"]["prepare_ms"]):
            ax.plot(smooth(series, window), label=f"client {i + 1}")
        ax.set_title(f"{s['scene']}: prepare occlusion queries, {r['clients']} clients (mean of {window} frames)")
        ax.set_xlabel("frame")
        ax.set_ylabel("ms")
        ax.legend(fontsize=7, ncol=4)
    save(fig, "query_prepare.png")

    if any(len(scaling_runs(s)) > 1 for s in scenes):
        # speed-up and work inflation against client count, one line per scene
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8))
        ns = sorted({r["clients"] for s in scenes for r in scaling_runs(s)})
        a1.plot(ns, ns, "k:", label="ideal")
        for s in scenes:
            runs = [r for r in scaling_runs(s) if r.get("derived_speedup_vs_1_client") is not None]
            line, = a1.plot([r["clients"] for r in runs], [r["derived_speedup_vs_1_client"] for r in runs], "o-",
                            label=s["scene"])
            a2.plot([r["clients"] for r in runs], [r["inflation"]["cpu_ms"] or float("nan") for r in runs], "o-",
                    color=line.get_color(), label=f"{s['scene']} CPU")
            a2.plot([r["clients"] for r in runs], [r["inflation"]["triangles"] or float("nan") for r in runs], "x--",
                    color=line.get_color(), label=f"{s['scene']} triangles")
        for ax in (a1, a2):
            ax.set_xscale("log", base=2)
            ax.set_xticks(ns)
            ax.set_xticklabels([str(n) for n in ns])
            ax.set_xlabel("clients")
            ax.legend(fontsize=7)
        a1.set_yscale("log", base=2)
        a1.set_yticks(ns)
        a1.set_yticklabels([str(n) for n in ns])
        a1.set_title("derived speed-up over 1 client")
        a2.set_title("work summed over clients / 1 client")
        save(fig, "scaling.png")

    if not any(sweep_runs(s) for s in scenes):
        return made  # no visibility-settings sweep in this suite: no speed-against-error plot
    # speed against error: frame time against PSNR for the visibility settings
    fig, ax = plt.subplots(figsize=(7, 4))
    cap = 0.0
    pts = []
    for s in scenes:
        for r in s["runs"].values():
            if r["clients"] != s.get("sweep_clients", 1):
                continue
            p = r["accuracy"]["mean_psnr_db"]
            pts.append((s["scene"], r["query_threshold"], r["frame_ms_median"], p))
            if p != "inf":
                cap = max(cap, p)
    top = max(cap + 10, 60)
    markers = "osD^v<>"
    for i, s in enumerate(scenes):
        mine = [(t, x, top if p == "inf" else p) for name, t, x, p in pts if name == s["scene"]]
        if mine:
            ax.scatter([x for _, x, _ in mine], [y for _, _, y in mine], marker=markers[i % len(markers)],
                       label=s["scene"])
            for t, x, y in mine:
                ax.annotate(f"T={t}", (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.axhline(top, color="grey", lw=0.5)
    ax.text(0.01, 0.97, f"identical frames plotted at {top:.0f} dB", transform=ax.transAxes, fontsize=7, va="top")
    ax.set_xlabel("median frame time, ms (measured)")
    ax.set_ylabel("mean PSNR vs reference, dB")
    ax.set_title("Speed against error (--query-threshold)")
    ax.legend(fontsize=8)
    save(fig, "speed_error.png")
    return made


def osg_paragraph(meta, scenes):
    if not meta.get("osg_baseline", True):
        return ("Baseline not run at this scale (`osg_baseline = false`): OpenSceneGraph's own single-node path "
                "(osg-occlusion) is left out.")
    if not any(s.get("osg") for s in scenes):
        return "Baseline not in this run: OpenSceneGraph's own single-node path (no osg-occlusion runs found)."
    o = meta.get("osg", {})
    return ("**osg-occlusion** is OpenSceneGraph's own best single-node path on the original model, run in the same "
            "session: `dmmr-osgviewer` (osgViewer embedded in an OSMesa compatibility context, single-threaded, "
            "same walkthrough, camera and image size) with `osg::OcclusionQueryNode` "
            f"{'inserted above every group of more than ' + str(o.get('min_vertices', 5000)) + ' vertices' if o.get('occlusion', 'on') == 'on' else 'NOT inserted (--occlusion off)'}"
            f" (visibility threshold {o.get('visibility_threshold', 0)} samples, a query every "
            f"{o.get('query_frame_count', 1)} frame(s)), OSG's view-frustum and small-feature culling, near and far "
            "planes from what it draws. Its frame time is timed as dmmr-reference's (frame to PNG written); its frames "
            "are not compared with the reference (OSG shades with fixed-function lighting). \"vs osg-occlusion\" is "
            "its mean frame time over the configuration's: above 1 the configuration is faster.")


def lp_line(meta):
    lp, rlp = meta.get("lp_num_threads") or "default", meta.get("render_lp_num_threads")
    if rlp is None or str(rlp) == str(lp):
        return f"LP_NUM_THREADS={lp} for every run"
    return f"LP_NUM_THREADS={lp} for the reference runs, {rlp} for dmmr-render (`--cost {meta.get('cost')}`)"


def write(report_dir, meta, scenes, window):
    report_dir = Path(report_dir)
    report_dir.mkdir(parents=True, exist_ok=True)
    csv_dir = report_dir / "csv"
    csv_dir.mkdir(exist_ok=True)
    for s in scenes:
        rd = Path(s["runs_dir"])
        for p in sorted(rd.glob("*.csv")):
            shutil.copy(p, csv_dir / f"{s['scene']}-{p.name}")
    made = plots(scenes, report_dir / "plots", window)
    ok = all(r["accuracy_ok"] for s in scenes for r in s["runs"].values())
    summary = dict(meta)
    summary["accuracy_ok"] = ok
    summary["plots"] = [f"plots/{m}" for m in made]
    scaling = meta.get("report") == "scaling"
    checks = check_targets(meta, scenes) if scaling else None
    if scaling:
        summary["targets_check"] = checks
    summary["scenes"] = []
    for s in scenes:
        s2 = json.loads(json.dumps(s, default=str))
        s2["reference"].pop("frame_ms_series", None)
        if s2.get("osg"):
            s2["osg"].pop("frame_ms_series", None)
        for r in s2["runs"].values():
            r.pop("series", None)
        summary["scenes"].append(s2)
    (report_dir / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False, default=str) + "\n")

    md = [f"# dmmr-bench: suite `{meta['suite']}`, scale `{meta['scale']}`", "",
          f"Command: `{meta['command']}`  ", f"Machine: {meta['machine']}  ",
          f"Images {meta['width']}x{meta['height']}, backend {meta['backend']}, "
          f"{lp_line(meta)}; "
          f"wall time of the whole suite {meta['wall_s']:.0f} s"
          f"{' (resumed: runs reused from an earlier invocation not counted)' if meta.get('resumed') else ''}.", ""]
    if scaling:
        md += [method_section(meta)]
    md += ["**Measured** times are wall-clock on this machine, where the server and all clients share its cores: "
          "with more clients than cores they slow each other down. **Derived** times are what a cluster with one "
          "machine per client would see, computed per frame from the measured stage times: server culling and "
          "division plus the slowest client's own work (prepare queries, retrieve, load, render, read back, "
          f"compress) and the transfer of its sub-frame over a nominal {meta.get('link_gbps', 1.0):g} Gbit/s link, "
          "no overlap between frames; the hand-over times (pass on, send) are left out of the derived times "
          "because on a shared machine they mostly measure waiting for another process; \"stages overlapped\" takes the slowest of server, "
          "visibility stage and render stage instead, as the pipeline would on a real cluster. Ratios compare "
          "with dmmr-reference (brute force, one process) measured in the same run: above 1 dmmr is faster. "
          "Efficiency is tau_1 / (S tau_S) over derived times. Frame 0 (cold caches) is left out of the means.", "",
          f"**Client cost used for the derived times (`--cost {meta.get('cost', 'wall')}`):** a client's work is "
          f"its {meta.get('derived_definition', '').split('is its ', 1)[-1]}.", "",
          "## Where dmmr stands", "", verdict(scenes),
          f"Accuracy: every conservative run (query threshold 0) {'matches' if ok else 'does NOT match'} the "
          "reference pixel for pixel" + ("." if ok else ": see the FAIL rows below."), "",
          osg_paragraph(meta, scenes), ""]
    if scaling:
        md += [scaling_section(meta, scenes, checks)]
    md += ["## Summary", "", summary_table(scenes),
          "## Stage times (the paper's Tables 1 to 3)", ""]
    for n in sorted({r["clients"] for s in scenes for r in s["runs"].values() if r.get("plain", not r["options"])}):
        md += [table_for_clients(scenes, n), ""]
    if any(sweep_runs(s) for s in scenes):
        md += ["## Speed against error (visibility settings)", "",
               "Threshold 0 is the plain run (the default, exact depth-pyramid test); thresholds above 0 are "
               "hardware occlusion queries (`--visibility queries --stages split --query-threshold T`).", "",
               sweep_table(scenes), ""]
    md += ["## Plots", ""]
    for m in made:
        md.append(f"![{m}](plots/{m})")
        md.append("")
    md += ["## Files", "", "`summary.json` (every figure above), `csv/SCENE-RUN.csv` (per-frame stats of each run; "
           "`*.cmp.csv`: per-frame PSNR and differing pixels against the reference), `plots/*.png`.", ""]
    (report_dir / "report.md").write_text("\n".join(md))
    return ok
