"""Per-run statistics from the per-frame CSVs: means per stage, the derived
cluster frame time, cache hit rates, accuracy against the reference."""
import csv
import json
import math
import statistics as st
from pathlib import Path

# Client columns of dmmr-render's stats CSV, in pipeline order.
VIS_STAGES = ["prepare_ms", "retrieve_ms", "pass_ms"]           # visibility context
RENDER_STAGES = ["load_ms", "render_ms", "readback_ms", "compress_ms", "send_ms"]  # render context
CLIENT_STAGES = VIS_STAGES + RENDER_STAGES
CLIENT_COUNTS = ["objects", "occluders", "queried", "visible", "triangles", "bytes_raw", "bytes_sent",
                 "gpu_hits", "gpu_misses", "ram_hits", "ram_misses", "disk_bytes"]
SERVER_STAGES = ["cull_ms", "divide_ms", "send_ms", "assemble_ms", "write_ms"]


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def steady(rows):
    """Frames 1.. (frame 0 loads every geometry it sees); all frames if only one."""
    return rows[1:] if len(rows) > 1 else rows


def num(r, k, default=0.0):
    v = r.get(k)
    if v is None or v == "":
        return default
    return float(v)


def mean(xs):
    xs = list(xs)
    return st.fmean(xs) if xs else float("nan")


def median(xs):
    xs = list(xs)
    return st.median(xs) if xs else float("nan")


def clients_of(row):
    n = 0
    while f"c{n + 1}_triangles" in row:
        n += 1
    return n


# The client's own work: the stages that compute, not those that hand over and
# may block (pass_ms waits for room in the render stage's queue, send_ms for
# MPI), which on a shared machine mostly measure waiting for another process.
WORK_VIS = ["prepare_ms", "retrieve_ms"]
WORK_RENDER = ["load_ms", "render_ms", "readback_ms", "compress_ms"]
LINK_GBPS = 1.0  # nominal network for the derived transfer time (set by the suite's run.link_gbps)
# Which per-client cost the derived times use (set by dmmr-bench --cost):
#   wall:  the stages' wall times (on a shared machine: waiting for a core included);
#   cpu:   the stage threads' CPU time (vis_cpu_ms + render_cpu_ms; the runs set
#          LP_NUM_THREADS=0 so llvmpipe rasterises on those threads);
#   user:  cpu less the stage threads' kernel time (cN_vis_sys_ms +
#          cN_render_sys_ms): leaves out page faults' kernel time, whose cost on
#          a virtual machine depends on the host and varies from run to run;
#   turns: the stages' wall times, taken with dmmr-render --stage-turns (one GL
#          stage at a time on the machine).
COST = "wall"
COST_DEFINITIONS = {
    "wall": "stage wall times (prepare+retrieve+load+render+readback+compress), which include "
            "waiting for a core when processes share the machine",
    "cpu": "stage threads' CPU time (vis_cpu_ms + render_cpu_ms, CLOCK_THREAD_CPUTIME_ID), "
           "dmmr-render run with LP_NUM_THREADS=0 so that llvmpipe rasterises on the stage threads",
    "user": "stage threads' user CPU time (vis_cpu_ms + render_cpu_ms less vis_sys_ms + render_sys_ms, the "
            "kernel part from getrusage(RUSAGE_THREAD)), dmmr-render run with LP_NUM_THREADS=0",
    "turns": "stage wall times (prepare+retrieve+load+render+readback+compress) with "
             "dmmr-render --stage-turns: one GL stage at a time on the machine",
}


def transfer_ms(nbytes):
    return nbytes * 8 / (LINK_GBPS * 1e9) * 1e3


def server_work(r, cost=None):
    """The server's culling and division in the frame: by `cost` "cpu" the CPU
    time of the threads that did them (plan_cpu_ms; CSVs from before it was
    recorded fall back to the wall times), else their wall times."""
    if (cost or COST) in ("cpu", "user") and r.get("plan_cpu_ms") not in (None, ""):
        return num(r, "plan_cpu_ms")
    return num(r, "cull_ms") + num(r, "divide_ms")


def client_work(r, k, cost=None):
    """Client k's own work in the frame, by `cost` (default COST)."""
    c = cost or COST
    if c in ("cpu", "user"):
        return stage_work(r, k, "vis", c) + stage_work(r, k, "render", c)
    return sum(num(r, f"c{k}_{s}") for s in WORK_VIS + WORK_RENDER)


def stage_work(r, k, stage, cost=None):
    """Client k's visibility ("vis") or render ("render") stage work, by `cost`."""
    c = cost or COST
    if c == "cpu":
        return num(r, f"c{k}_{stage}_cpu_ms")
    if c == "user":
        return num(r, f"c{k}_{stage}_cpu_ms") - num(r, f"c{k}_{stage}_sys_ms")
    return sum(num(r, f"c{k}_{s}") for s in (WORK_VIS if stage == "vis" else WORK_RENDER))


def derived_frame(r, n, cost=None):
    """The frame time a cluster with one machine per client would see, from this
    frame's measured stage costs (by `cost`, default COST): server cull and
    division, then the slowest client's own work done serially (prepare,
    retrieve, load, render, read back, compress) plus its sub-frame's transfer
    at LINK_GBPS; no overlap between frames assumed. Waiting (pass_ms, send_ms)
    is left out."""
    server = server_work(r, cost)
    slowest = max(client_work(r, k, cost) + transfer_ms(num(r, f"c{k}_bytes_sent"))
                  for k in range(1, n + 1))
    return server + slowest


def derived_pipelined(r, n):
    """Same, with the stages overlapped as the pipeline does on a real cluster
    (two contexts per client): the slowest of server, visibility and render stage."""
    server = server_work(r)
    vis = max(stage_work(r, k, "vis") for k in range(1, n + 1))
    ren = max(stage_work(r, k, "render") + transfer_ms(num(r, f"c{k}_bytes_sent"))
              for k in range(1, n + 1))
    return max(server, vis, ren)


def in_flight_of(options, default=3):
    """dmmr-render's --in-flight from a run's options (a list, or one string;
    dmmr-render's default 3 when absent)."""
    words = options.split() if isinstance(options, str) else [str(w) for w in (options or [])]
    for i, w in enumerate(words):
        if w == "--in-flight" and i + 1 < len(words):
            return int(words[i + 1])
        if w.startswith("--in-flight="):
            return int(w.split("=", 1)[1])
    return default


def schedule(server_ms, client_ms, transfer, in_flight, first=1):
    """dmmr's frame schedule replayed on a cluster with one machine per client,
    from per-frame costs: the server plans frame f once frame f - in_flight is
    assembled (Assembler::waitForRoom), one frame after another; each client
    works through its jobs in order, starting a job when its previous one and
    the frame's plan are done, and is busy until its sub-frame has left
    (transfer included); a frame is assembled when its last sub-frame is in.
    server_ms[f]: planning cost; client_ms[f][k], transfer[f][k]: client k's
    cost and transfer. Returns (period, latency): the mean time between
    assemblies over frames `first`.. (1: all but the first), and the mean over
    them of the time from a frame's planning start to its assembly. Pure
    function over plain lists."""
    frames = len(server_ms)
    if frames == 0:
        return float("nan"), float("nan")
    n = len(client_ms[0])
    done, began = [0.0] * frames, [0.0] * frames
    server_free, client_free = 0.0, [0.0] * n
    for f in range(frames):
        began[f] = max(server_free, done[f - in_flight] if f >= in_flight else 0.0)
        server_free = began[f] + server_ms[f]
        arrivals = []
        for k in range(n):
            client_free[k] = max(client_free[k], server_free) + client_ms[f][k] + transfer[f][k]
            arrivals.append(client_free[k])
        done[f] = max(arrivals)
    if frames == 1:
        return done[0], done[0] - began[0]
    first = min(max(first, 1), frames - 1)
    return ((done[-1] - done[first - 1]) / (frames - first),
            mean(done[f] - began[f] for f in range(first, frames)))


def derived_schedule(rows, n, in_flight, cost=None, first=1):
    """schedule() over a run's stats rows (every frame, in order), with the
    costs derived_frame uses (server_work, client_work by `cost`, transfer at
    LINK_GBPS)."""
    return schedule([server_work(r, cost) for r in rows],
                    [[client_work(r, k, cost) for k in range(1, n + 1)] for r in rows],
                    [[transfer_ms(num(r, f"c{k}_bytes_sent")) for k in range(1, n + 1)] for r in rows],
                    in_flight, first)


def accuracy(cmp_path):
    rows = read_csv(cmp_path)
    ps = [float(r["psnr"]) for r in rows]
    finite = [p for p in ps if not math.isinf(p)]
    return {
        "frames": len(rows),
        "max_differing_pixels": max((int(r["differing_pixels"]) for r in rows), default=0),
        "total_differing_pixels": sum(int(r["differing_pixels"]) for r in rows),
        "min_psnr_db": min(finite) if finite else "inf",
        "mean_psnr_db": mean(finite) if finite else "inf",
        "identical_frames": sum(1 for r in rows if int(r["differing_pixels"]) == 0),
    }


def rate(h, m):
    return h / (h + m) if h + m > 0 else None


def reference_stats(path):
    rows = read_csv(path)
    s = steady(rows)
    ft = [num(r, "frame_ms") for r in s]
    return {
        "frames": len(rows),
        "frame_ms_mean": mean(ft), "frame_ms_median": median(ft),
        "frame_ms_series": [num(r, "frame_ms") for r in rows],
        "fps": 1000.0 / mean(ft) if mean(ft) > 0 else None,
        "triangles_mean": mean(num(r, "triangles") for r in s),
    }


def osg_stats(path):
    """dmmr-osgviewer's CSV (frame, frame_ms, draw_ms, drawables, triangles): timed as the
    reference is (frame_ms includes writing the PNG, draw_ms ends after glReadPixels)."""
    rows = read_csv(path)
    s = steady(rows)
    ft = [num(r, "frame_ms") for r in s]
    return {
        "frames": len(rows),
        "frame_ms_mean": mean(ft), "frame_ms_median": median(ft),
        "frame_ms_series": [num(r, "frame_ms") for r in rows],
        "fps": 1000.0 / mean(ft) if mean(ft) > 0 else None,
        "draw_ms_mean": mean(num(r, "draw_ms") for r in s),
        "drawables_mean": mean(num(r, "drawables") for r in s),
        "triangles_mean": mean(num(r, "triangles") for r in s),
    }


def faster(base, x):
    """base / x: above 1, x is faster than base by that factor; None when undefined."""
    if x is None or base is None or math.isnan(x) or math.isnan(base) or x <= 0:
        return None
    return base / x


def has_kernel_time(row):
    """Whether a stats row has the stage threads' kernel time and faults (CSVs from before have not)."""
    return "c1_render_sys_ms" in row


def max_over_mean(rows, n, cost=None):
    """Median over `rows` of each frame's max over clients / mean over clients of client_work."""
    return median(max(w) / mean(w) if mean(w) > 0 else 1.0
                  for w in ([client_work(r, k, cost) for k in range(1, n + 1)] for r in rows))


def client_costs(rows, n, cost=None):
    """Per row, the list of its n clients' client_work."""
    return [[client_work(r, k, cost) for k in range(1, n + 1)] for r in rows]


# The figures compared between a frame's slowest client and its mean client:
# key -> (label, per-client value of a row). "pixels" is the region's size
# (RGB bytes read back / 3).
SLOWEST_FIGURES = {
    "objects": ("objects listed", lambda r, k: num(r, f"c{k}_objects")),
    "queried": ("objects tested", lambda r, k: num(r, f"c{k}_queried")),
    "visible": ("objects drawn", lambda r, k: num(r, f"c{k}_visible")),
    "triangles": ("triangles drawn", lambda r, k: num(r, f"c{k}_triangles")),
    "submitted": ("triangles submitted", lambda r, k: num(r, f"c{k}_submitted")),
    "pixels": ("pixels", lambda r, k: num(r, f"c{k}_bytes_raw") / 3),
}


def slowest_client_profile(rows, costs):
    """What a frame's slowest client did against the frame's mean client.

    `costs`: per row, its clients' work (client_costs). For each row, the
    client of largest work is the slowest; each
    figure of SLOWEST_FIGURES (and "cost" itself) is taken as the slowest
    client's value over the mean of the n clients' values, and the result is
    the median of that ratio over the rows where the mean is positive (None
    where no row has one). Rows where every client cost 0 have no slowest
    client and are left out. A cost ratio well above 1 with count ratios near 1
    means the slowest client did as much as the others, only slower (noise or
    a cost the counts do not see); count ratios as high as the cost's mean
    its region held more of the work than the division planned."""
    out = {}
    n = len(costs[0]) if costs else 0
    slow = [max(range(n), key=lambda i: c[i]) + 1 for c in costs]
    figures = dict(SLOWEST_FIGURES, cost=("cost", None))
    for key, (_, fn) in figures.items():
        ratios = []
        for r, c, k in zip(rows, costs, slow):
            if max(c) <= 0:
                continue
            vals = c if fn is None else [fn(r, j) for j in range(1, n + 1)]
            m = sum(vals) / n
            if m > 0:
                ratios.append(vals[k - 1] / m)
        out[key] = median(ratios) if ratios else None
    return out


def share_correlation(costs, lag):
    """Pearson correlation of a client's share of a frame's work (its entry of
    `costs`, per frame its clients' work as client_costs gives it, over the
    frame's mean) with its share `lag` frames later, pooled over the
    clients and frames. The server plans a frame with the clients' feedback of
    `in_flight` frames before, and the shares are measured after it acted on
    that feedback: at that lag, a correlation near 0 says that what its
    correction leaves is not predictable from shares that old. None with
    fewer than three pairs or no spread."""
    shares = []
    for c in costs:
        m = sum(c) / len(c)
        shares.append([x / m for x in c] if m > 0 else None)
    xs, ys = [], []
    for a, b in zip(shares, shares[lag:]):
        if a is not None and b is not None:
            xs += a
            ys += b
    if len(xs) < 3:
        return None
    mx, my = mean(xs), mean(ys)
    sxy = sum((x - mx) * (y - my) for x, y in zip(xs, ys))
    sxx = sum((x - mx) ** 2 for x in xs)
    syy = sum((y - my) ** 2 for y in ys)
    return sxy / math.sqrt(sxx * syy) if sxx > 0 and syy > 0 else None


def efficiency_parts(base, run):
    """The derived efficiency tau_1 / (S tau_S) of `run` against the 1-client
    `base` as an exact product of four factors (each from render_stats):

      one_client = tau_1 / W_1   the 1-client frame over its client's work (>= 1:
                                 the server's plan and the transfer on top)
      work       = W_1 / W_S     1 / inflation of the clients' summed work
      balance    = (W_S / S) / M_S   the mean client over the slowest, each
                                 a mean over frames (not the median max/mean)
      server     = M_S / tau_S   the slowest client's work over the frame (the
                                 server's plan and the transfer on top)

    W is the mean over frames of the clients' summed work, M the mean over
    frames of the largest client's work, tau the derived frame time. None if a
    figure is missing or zero."""
    try:
        t1, w1 = base["derived_frame_ms_mean"], base["client_cost_sum_mean"]
        ts, s = run["derived_frame_ms_mean"], run["clients"]
        ws, ms = run["client_cost_sum_mean"], run["client_cost_max_mean"]
    except KeyError:
        return None
    if min(t1, w1, ts, ws, ms) <= 0:
        return None
    parts = {"one_client": t1 / w1, "work": w1 / ws, "balance": ws / s / ms, "server": ms / ts}
    parts["efficiency"] = t1 / (s * ts)
    return parts


def render_stats(path, clients, in_flight=3):
    rows = read_csv(path)
    n = clients_of(rows[0])
    if n != clients:
        raise RuntimeError(f"{path}: {n} clients in the CSV, {clients} expected")
    s = steady(rows)
    ft = [num(r, "frame_ms") for r in s]
    der = [derived_frame(r, n) for r in s]
    derp = [derived_pipelined(r, n) for r in s]
    costs = client_costs(s, n)
    period, latency = derived_schedule(rows, n, in_flight)
    out = {
        "frames": len(rows), "clients": n,
        "frame_ms_mean": mean(ft), "frame_ms_median": median(ft),
        "fps": 1000.0 / mean(ft) if mean(ft) > 0 else None,
        "fps_min": 1000.0 / max(ft) if ft and max(ft) > 0 else None,
        "fps_max": 1000.0 / min(ft) if ft and min(ft) > 0 else None,
        "derived_frame_ms_mean": mean(der), "derived_frame_ms_median": median(der),
        "derived_pipelined_ms_mean": mean(derp),
        # the run's own schedule (in_flight frames ahead) replayed on a cluster
        "in_flight": in_flight,
        "scheduled_frame_ms": period, "scheduled_latency_ms": latency,
        "derived_cost": COST,
        # both costs where the CSV has CPU times, to check one against the other
        "derived_wall_frame_ms_mean": mean(derived_frame(r, n, "wall") for r in s),
        "derived_cpu_frame_ms_mean": (mean(derived_frame(r, n, "cpu") for r in s)
                                      if "c1_render_cpu_ms" in rows[0] else None),
        # max over clients / mean over clients of each frame's work, median over frames
        "client_max_over_mean_median": max_over_mean(s, n),
        # for efficiency_parts: the clients' summed and largest work, means over frames
        "client_cost_sum_mean": mean(sum(c) for c in costs),
        "client_cost_max_mean": mean(max(c) for c in costs),
        # what each frame's slowest client did against its mean client, and
        # whether a client's share repeats 1 frame and in_flight frames later
        "slowest_client": slowest_client_profile(s, costs) if n > 1 else None,
        "share_correlation": ({1: share_correlation(costs, 1), in_flight: share_correlation(costs, in_flight)}
                              if n > 1 else None),
        "server": {k: mean(num(r, k) for r in s) for k in SERVER_STAGES},
        "objects_in_frustum_mean": mean(num(r, "objects_in_frustum") for r in s),
        "triangles_in_frustum_mean": mean(num(r, "triangles_in_frustum") for r in s),
        "series": {
            "frame_ms": [num(r, "frame_ms") for r in rows],
            "derived_frame_ms": [derived_frame(r, n) for r in rows],
            "divide_ms": [num(r, "divide_ms") for r in rows],
            "prepare_ms": [[num(r, f"c{k}_prepare_ms") for r in rows] for k in range(1, n + 1)],
        },
        "per_client": [],
    }
    if has_kernel_time(rows[0]):
        # the same figures by user CPU (cost "user"): what the kernel's page
        # faults take is left out (see COST_DEFINITIONS)
        out["derived_user_frame_ms_mean"] = mean(derived_frame(r, n, "user") for r in s)
        out["scheduled_user_frame_ms"] = derived_schedule(rows, n, in_flight, "user")[0]
        out["client_max_over_mean_user_median"] = max_over_mean(s, n, "user")
    gh = gm = rh = rm = 0.0
    for k in range(1, n + 1):
        c = {st_: mean(num(r, f"c{k}_{st_}") for r in s) for st_ in CLIENT_STAGES}
        c.update({f"{cnt}_mean": mean(num(r, f"c{k}_{cnt}") for r in s) for cnt in CLIENT_COUNTS})
        c["work_ms"] = sum(c[x] for x in WORK_VIS + WORK_RENDER)
        c["vis_cpu_ms"] = mean(num(r, f"c{k}_vis_cpu_ms") for r in s)
        c["render_cpu_ms"] = mean(num(r, f"c{k}_render_cpu_ms") for r in s)
        if has_kernel_time(rows[0]):
            c["sys_ms"] = mean(num(r, f"c{k}_vis_sys_ms") + num(r, f"c{k}_render_sys_ms") for r in s)
            c["faults_mean"] = mean(num(r, f"c{k}_vis_faults") + num(r, f"c{k}_render_faults") for r in s)
        c["cost_ms"] = mean(client_work(r, k) for r in s)
        c["transfer_ms"] = transfer_ms(c["bytes_sent_mean"])
        hits = {x: sum(num(r, f"c{k}_{x}") for r in s) for x in ("gpu_hits", "gpu_misses", "ram_hits", "ram_misses")}
        c["gpu_hit_rate"] = rate(hits["gpu_hits"], hits["gpu_misses"])
        c["ram_hit_rate"] = rate(hits["ram_hits"], hits["ram_misses"])
        gh += hits["gpu_hits"]; gm += hits["gpu_misses"]; rh += hits["ram_hits"]; rm += hits["ram_misses"]
        out["per_client"].append(c)
    out["triangles_drawn_mean"] = sum(c["triangles_mean"] for c in out["per_client"])
    out["bytes_sent_mean"] = sum(c["bytes_sent_mean"] for c in out["per_client"])
    out["gpu_hit_rate"] = rate(gh, gm)
    out["ram_hit_rate"] = rate(rh, rm)
    return out


# The work a run does, summed over its clients (means over frames 1..): what
# the scaling report divides by the 1-client run's to show work inflation.
# key -> (label, per-client figure from render_stats' per_client entries)
WORK_SUMS = {
    "queried": ("objects tested", lambda c: c["queried_mean"]),
    "visible": ("objects drawn", lambda c: c["visible_mean"]),
    "triangles": ("triangles drawn", lambda c: c["triangles_mean"]),
    "occluders": ("occluders drawn (objects)", lambda c: c["occluders_mean"]),
    "pixels": ("pixels read back", lambda c: c["bytes_raw_mean"] / 3),  # RGB sub-frames
    "cpu_ms": ("client CPU ms", lambda c: c["vis_cpu_ms"] + c["render_cpu_ms"]),
}


def work_sums(r):
    return {k: sum(fn(c) for c in r["per_client"]) for k, (_, fn) in WORK_SUMS.items()}


def scene_counts(scene_dir):
    try:
        m = json.loads((Path(scene_dir) / "manifest.json").read_text())
        return m.get("counts", {})
    except (OSError, ValueError):
        return {}


def run_labels(label, repeats):
    """The labels of a configuration's runs: `label`, then label.r2 .. label.rN."""
    return [label] + [f"{label}.r{k}" for k in range(2, repeats + 1)]


def run_order(labels, repeats):
    """The order of a scene's dmmr-render runs: `repeats` rounds, each running
    every configuration once (in `labels` order) as (label, run label). On a
    shared virtual machine the host's memory traffic slows memory-bound work
    by up to 1.5x for a minute at a time while arithmetic runs at full speed
    (docs/benchmarks.md, "A machine-speed probe"): run back to back, all of
    one configuration's repeats could fall in one slow spell; in rounds each
    spell is shared among the configurations."""
    return [(label, run_labels(label, repeats)[k]) for k in range(repeats) for label in labels]


def median_run(costs):
    """Index of the median of `costs` (one figure per repeated run): the lower
    middle one for an even count, so that the pick is always one of the runs."""
    if not costs:
        raise ValueError("median_run: no runs")
    order = sorted(range(len(costs)), key=lambda i: (costs[i], i))
    return order[(len(costs) - 1) // 2]


def analyse_scene(name, info, configurations, repeats=1):
    rd = Path(info["runs_dir"])
    ref = reference_stats(rd / "reference.csv")
    res = {"scene": name, "counts": scene_counts(info["scene_dir"]), "walkthrough": info["walkthrough"],
           "reference": ref, "runs": {}}
    # the OpenSceneGraph baseline (dmmr-osgviewer), when its run is there
    osg = osg_stats(info["osg_csv"]) if info.get("osg_csv") and Path(info["osg_csv"]).exists() else None
    if osg:
        osg["speedup_vs_reference"] = faster(ref["frame_ms_mean"], osg["frame_ms_mean"])
    res["osg"] = osg
    of = osg["frame_ms_mean"] if osg else None
    for label, n, extra in configurations:
        # Repeated runs (dmmr-bench --repeats): the one of median summed client
        # cost stands for the configuration; every run's figures are kept.
        labels = [rl for rl in run_labels(label, repeats) if (rd / f"{rl}.csv").exists()] or [label]
        tries = [render_stats(rd / f"{rl}.csv", n, in_flight_of(extra)) for rl in labels]
        accs = [accuracy(rd / f"{rl}.cmp.csv") for rl in labels]
        pick = median_run([work_sums(t)["cpu_ms"] for t in tries])
        r = tries[pick]
        r["repeats"] = [{"label": rl, "cpu_ms": work_sums(t)["cpu_ms"], "derived_frame_ms": t["derived_frame_ms_mean"],
                         "scheduled_frame_ms": t["scheduled_frame_ms"],
                         "max_differing_pixels": a["max_differing_pixels"], "used": i == pick}
                        for i, (rl, t, a) in enumerate(zip(labels, tries, accs))]
        r["options"] = extra
        r["plain"] = "--query-threshold" not in extra  # a plain run (options given to all of them aside)
        r["query_threshold"] = int(extra[extra.index("--query-threshold") + 1]) if "--query-threshold" in extra else 0
        r["conservative"] = r["query_threshold"] == 0
        r["accuracy"] = accs[pick]
        # every repeat must be exact, not only the one whose figures are shown
        r["accuracy_ok"] = all(a["max_differing_pixels"] == 0 for a in accs) if r["conservative"] else True
        rf = ref["frame_ms_mean"]
        # > 1: dmmr is faster than the reference by that factor; < 1: it loses
        r["speedup_vs_reference"] = rf / r["frame_ms_mean"] if r["frame_ms_mean"] > 0 else None
        r["derived_speedup_vs_reference"] = rf / r["derived_frame_ms_mean"] if r["derived_frame_ms_mean"] > 0 else None
        # the same against OSG's own path (osgViewer + OcclusionQueryNode on the original model)
        r["speedup_vs_osg"] = faster(of, r["frame_ms_mean"])
        r["derived_speedup_vs_osg"] = faster(of, r["derived_frame_ms_mean"])
        res["runs"][label] = r
    # efficiency tau_1 / (S * tau_S) over the plain runs, from derived times
    base = next((r for r in res["runs"].values() if r["clients"] == 1 and r["plain"]), None)
    for r in res["runs"].values():
        if base and r["plain"] and r["derived_frame_ms_mean"] > 0:
            r["derived_efficiency"] = base["derived_frame_ms_mean"] / (r["clients"] * r["derived_frame_ms_mean"])
            r["derived_speedup_vs_1_client"] = base["derived_frame_ms_mean"] / r["derived_frame_ms_mean"]
        if base and r["plain"] and r["scheduled_frame_ms"] > 0:
            r["scheduled_efficiency"] = base["scheduled_frame_ms"] / (r["clients"] * r["scheduled_frame_ms"])
            r["scheduled_speedup_vs_1_client"] = base["scheduled_frame_ms"] / r["scheduled_frame_ms"]
        if base and r["plain"] and base.get("scheduled_user_frame_ms") and r.get("scheduled_user_frame_ms"):
            r["scheduled_user_efficiency"] = base["scheduled_user_frame_ms"] / (
                r["clients"] * r["scheduled_user_frame_ms"])
            r["derived_user_efficiency"] = base["derived_user_frame_ms_mean"] / (
                r["clients"] * r["derived_user_frame_ms_mean"])
    for r in res["runs"].values():
        if base and r["plain"] and r is not base:
            r["efficiency_parts"] = efficiency_parts(base, r)
    # work inflation: each run's work summed over clients against the 1-client run's
    for r in res["runs"].values():
        r["work_sums"] = work_sums(r)
    for r in res["runs"].values():
        if base and r["plain"]:
            r["inflation"] = {k: (v / base["work_sums"][k] if base["work_sums"][k] > 0 else None)
                              for k, v in r["work_sums"].items()}
    return res
