"""The report: summary.json, tables as Markdown, plots as PNG, per-frame CSVs."""
import json
import math
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
          f"LP_NUM_THREADS={meta.get('lp_num_threads') or 'default'} for every run; "
          f"wall time of the whole suite {meta['wall_s']:.0f} s.", "",
          "**Measured** times are wall-clock on this machine, where the server and all clients share its cores: "
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
          osg_paragraph(meta, scenes), "",
          "## Summary", "", summary_table(scenes),
          "## Stage times (the paper's Tables 1 to 3)", ""]
    for n in sorted({r["clients"] for s in scenes for r in s["runs"].values() if r.get("plain", not r["options"])}):
        md += [table_for_clients(scenes, n), ""]
    md += ["## Speed against error (visibility settings)", "",
           "Threshold 0 is the plain run (the default, exact depth-pyramid test); thresholds above 0 are "
           "hardware occlusion queries (`--visibility queries --stages split --query-threshold T`).", "",
           sweep_table(scenes), "",
           "## Plots", ""]
    for m in made:
        md.append(f"![{m}](plots/{m})")
        md.append("")
    md += ["## Files", "", "`summary.json` (every figure above), `csv/SCENE-RUN.csv` (per-frame stats of each run; "
           "`*.cmp.csv`: per-frame PSNR and differing pixels against the reference), `plots/*.png`.", ""]
    (report_dir / "report.md").write_text("\n".join(md))
    return ok
