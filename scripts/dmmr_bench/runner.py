"""Generates (or reuses) the suite's scenes and runs every configuration."""
import atexit
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .analysis import run_labels, run_order


OSG_TOOL = "dmmr-osgviewer"
OSG_LABEL = "osg-occlusion"  # the OpenSceneGraph baseline's run, one per scene
# dmmr-osgviewer's settings, from the suite's [osg] table (the tool's defaults otherwise)
OSG_KEYS = {"occlusion": "--occlusion", "min_vertices": "--min-vertices",
            "visibility_threshold": "--visibility-threshold", "query_frame_count": "--query-frame-count"}


class Progress:
    def __init__(self, total):
        self.total, self.done, self.start = total, 0, time.monotonic()

    def step(self, what):
        self.done += 1
        elapsed = time.monotonic() - self.start
        print(f"[{self.done:>3}/{self.total}] {elapsed:7.1f} s  {what}", flush=True)


# mpirun's report of a rank that never started (no PID): a launch failure,
# seen rarely on this machine with other mpirun jobs starting at the same
# time, not a failure of the program launched.
LAUNCH_FAILURE = "with PID 0 on"


def children_usage():
    """User and kernel CPU seconds and minor page faults of this process's
    waited-for descendants so far (getrusage RUSAGE_CHILDREN: mpirun and,
    through it, every rank and their threads)."""
    u = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {"user_s": u.ru_utime, "sys_s": u.ru_stime, "minor_faults": u.ru_minflt}


def run_cmd(cmd, log, env=None, usage=None):
    """Runs cmd, appending its output to log; raises with the log's tail on failure.
    A run that mpirun reports as never launched is tried once more. `usage`
    (a dict, optional) gets the last attempt's whole-process CPU time and page
    faults (children_usage's keys): on a shared virtual machine a page fault's
    cost varies from run to run, and a run's kernel time shows it."""
    for attempt in range(2):
        t0 = time.monotonic()  # the last attempt's time
        u0 = children_usage()
        start = Path(log).stat().st_size if Path(log).exists() else 0
        with open(log, "a") as f:
            f.write("$ " + " ".join(str(c) for c in cmd) + "\n")
            f.flush()
            p = subprocess.run([str(c) for c in cmd], stdout=f, stderr=subprocess.STDOUT, env=env)
        if p.returncode == 0 or attempt == 1:
            break
        with open(log) as f:
            f.seek(start)
            if LAUNCH_FAILURE not in f.read():
                break
        with open(log, "a") as f:
            f.write("dmmr-bench: mpirun could not launch a rank; trying once more\n")
    dt = time.monotonic() - t0
    if usage is not None:
        u1 = children_usage()
        usage.update({k: u1[k] - u0[k] for k in u1})
    if p.returncode != 0:
        tail = Path(log).read_text().splitlines()[-15:]
        raise RuntimeError(f"command failed ({p.returncode}): {' '.join(str(c) for c in cmd)}\n" + "\n".join(tail))
    return dt


def window_lines(lines, start, count):
    """Control points start .. start + count - 1 of a walkthrough (its text
    lines: time, eye, rotation), their times moved so that the first is 0."""
    if start < 0 or count < 1 or start + count > len(lines):
        raise ValueError(f"window {start}..{start + count - 1} outside a walk of {len(lines)} points")
    t0 = float(lines[start].split()[0])
    return [" ".join([repr(float(w[0]) - t0)] + w[1:]) for w in (l.split() for l in lines[start:start + count])]


class Runner:
    def __init__(self, suite, scale, out, bin_dir, backend="osmesa", resume=False, render_options=(),
                 cost="wall", repeats=1, report_only=False):
        self.suite, self.scale, self.out, self.bin = suite, scale, Path(out), Path(bin_dir)
        self.backend, self.resume = backend, resume
        # --report-only: reuse what is there; anything missing is an error, never a run
        self.report_only = report_only
        # extra dmmr-render options of the plain runs (not the threshold sweep), e.g. --stages fused
        self.render_options = [str(o) for o in render_options]
        self.cfg = suite["scales"][scale]
        self.run_cfg = suite.get("run", {})
        self.log = self.out / "bench.log"
        for tool in ("dmmr-scenegen", "dmmr-preprocess", "dmmr-reference", "dmmr-render", "dmmr-compare",
                     OSG_TOOL):
            if not (self.bin / tool).exists():
                sys.exit(f"dmmr-bench: {self.bin / tool} not found (build it, or pass --bin / set DMMR_BIN)")
        self.env = dict(os.environ)
        lp = self.run_cfg.get("lp_num_threads")
        if lp:
            self.env["LP_NUM_THREADS"] = str(lp)
        # Each suite its own Open MPI session directory: 4.1 creates
        # <TMPDIR>/ompi.<host>.<uid> with a racy mkdir, so jobs started at once
        # (a suite beside the test suite) can fail (open-mpi/ompi#8510).
        session = tempfile.mkdtemp(prefix="dmmr-bench-mpi-")
        atexit.register(shutil.rmtree, session, True)
        self.env["TMPDIR"] = session
        self.mpi = ["mpirun", "--oversubscribe", "--bind-to", "none"]
        if os.geteuid() == 0:
            self.mpi.append("--allow-run-as-root")
        if lp:
            self.mpi += ["-x", "LP_NUM_THREADS"]
        # How the clients' costs are taken (analysis.COST_DEFINITIONS): cpu runs
        # dmmr-render with LP_NUM_THREADS=0 (rasterising on the stage threads,
        # so their CPU time is the whole cost), and so does user; turns with
        # --stage-turns.
        self.cost = cost
        self.render_env = dict(self.env)
        self.render_mpi = list(self.mpi)
        if cost in ("cpu", "user"):
            self.render_env["LP_NUM_THREADS"] = "0"
            if not lp:
                self.render_mpi += ["-x", "LP_NUM_THREADS"]
        self.render_extra = ["--stage-turns", str(self.out / "stage-turns.lock")] if cost == "turns" else []
        self.timings = {}  # label -> wall seconds
        self.usage = {}  # dmmr-render runs' label -> children_usage of the run
        # each dmmr-render configuration run this many times (run_labels); the
        # report takes the run of median cost (analysis.median_run)
        self.repeats = max(1, int(repeats))
        self.osg = self.osg_settings()  # checked before any run
        # the OpenSceneGraph baseline: on unless the scale (else the suite's
        # [run]) says osg_baseline = false; a scaling suite uses none of its
        # figures, and at a large scale it is one more single-node render
        self.osg_baseline = bool(self.cfg.get("osg_baseline", self.run_cfg.get("osg_baseline", True)))

    # --- plan -------------------------------------------------------------
    def configurations(self):
        """(label, clients, extra dmmr-render options) per scene, the sweep included."""
        confs = []
        for n in self.run_cfg.get("clients", [1, 2, 4]):
            confs.append((f"render-c{n}", n, list(self.render_options)))
        sweep_n = self.run_cfg.get("sweep_clients", 1)
        for t in self.run_cfg.get("query_thresholds", []):
            if t == 0 and sweep_n in self.run_cfg.get("clients", []):
                continue  # the plain run with sweep_n clients is threshold 0
            # Thresholds are a query setting (the default pyramid test is
            # exact and has none): the sweep runs the paper's queries.
            confs.append((f"render-c{sweep_n}-t{t}", sweep_n,
                          ["--visibility", "queries", "--stages", "split", "--query-threshold", str(t)]))
        return confs

    def run_labels(self, label):
        return run_labels(label, self.repeats)

    def scenes(self):
        return self.cfg["scenes"]

    def total_steps(self):
        # generate, preprocess, reference, OSG baseline, (render, compare)*
        per_scene = 2 + 1 + int(self.osg_baseline) + 2 * self.repeats * len(self.configurations())
        return per_scene * len(self.scenes())

    # --- scenes -----------------------------------------------------------
    def missing(self, what):
        """With --report-only, what would be run is an error instead."""
        if self.report_only:
            raise RuntimeError(f"--report-only: {what} is missing from {self.out}; run without --report-only "
                               "(add --resume to reuse what is there)")

    def make_scene(self, sc, progress):
        d = self.out / "scenes"
        d.mkdir(parents=True, exist_ok=True)
        name = sc["name"]
        osgb, path, scene_dir = d / f"{name}.osgb", d / f"{name}.path", d / f"{name}.scene"
        frames, path_frames = self.frames(sc), self.path_frames(sc)
        if not (osgb.exists() and path.exists() and (scene_dir / "manifest.json").exists()):
            self.missing(f"scene {name}")
        if osgb.exists() and path.exists() and len(self.path_lines(path)) == path_frames:
            progress.step(f"{name}: scene reused ({osgb})")
        else:
            kind = sc.get("kind", "replicate")
            cmd = [self.bin / "dmmr-scenegen", kind]
            if kind == "replicate":
                cmd += ["--of", sc["of"], "--copies", sc["copies"]]
            if "triangles" in sc:
                cmd += ["--triangles", sc["triangles"]]
            if "geodes" in sc:
                cmd += ["--geodes", sc["geodes"]]
            if "path" in sc:
                cmd += ["--path", sc["path"]]
            cmd += ["--seed", sc.get("seed", 1), "-o", osgb, "--walkthrough", path, "--frames", path_frames]
            dt = run_cmd(cmd, self.log)
            progress.step(f"{name}: generated in {dt:.1f} s")
        if (scene_dir / "manifest.json").exists():
            progress.step(f"{name}: preprocessed scene reused ({scene_dir})")
        else:
            if scene_dir.exists():
                shutil.rmtree(scene_dir)
            dt = run_cmd([self.bin / "dmmr-preprocess", osgb, "-o", scene_dir, "--no-progress"], self.log)
            progress.step(f"{name}: preprocessed in {dt:.1f} s")
        if path_frames != frames:
            path = self.window_path(path, frames, self.path_start(sc))
        return scene_dir, path, osgb

    # --- a window of a longer walk ----------------------------------------
    # The fly-through crosses the scene in however many control points it is
    # made with, so 40 of them move the camera five times as far a frame as
    # the paper suite's 200. A scale may set path_frames = P (> frames = F):
    # the scene's walk is made with P points and the runs render F consecutive
    # ones of it, from path_start (default: the middle F), so that the camera
    # moves as it does in the longer walk and the frames fit this machine.
    def frames(self, sc):
        """The frames a scene's runs render."""
        return int(sc.get("frames", self.cfg.get("frames", 40)))

    def path_frames(self, sc):
        frames = self.frames(sc)
        p = int(sc.get("path_frames", self.cfg.get("path_frames", frames)))
        if p < frames:
            sys.exit(f"dmmr-bench: path_frames ({p}) must be at least frames ({frames})")
        return p

    def path_start(self, sc):
        frames, p = self.frames(sc), self.path_frames(sc)
        start = int(sc.get("path_start", self.cfg.get("path_start", (p - frames) // 2)))
        if not 0 <= start <= p - frames:
            sys.exit(f"dmmr-bench: path_start ({start}) must be in 0..{p - frames} (path_frames - frames)")
        return start

    @staticmethod
    def path_lines(path):
        return [l for l in Path(path).read_text().splitlines() if l.strip()]

    def window_path(self, path, frames, start):
        sub = Path(path).with_suffix(f".points{start}-{start + frames - 1}.path")
        tmp = sub.with_suffix(".path.tmp")
        tmp.write_text("\n".join(window_lines(self.path_lines(path), start, frames)) + "\n")
        tmp.replace(sub)  # atomic: a run never reads half a walk
        return sub

    # --- runs -------------------------------------------------------------
    def common_opts(self, scene_dir, path, out_dir, stats):
        return ["--scene", scene_dir, "--walkthrough", path, "--out", out_dir, "--stats", stats,
                "--width", self.cfg.get("width", 512), "--height", self.cfg.get("height", 512),
                "--backend", self.backend, "--no-progress"]

    def osg_settings(self):
        """The [osg] table, checked: its keys are dmmr-osgviewer's options."""
        osg = dict(self.suite.get("osg", {}))
        unknown = sorted(set(osg) - set(OSG_KEYS))
        if unknown:
            sys.exit(f"dmmr-bench: unknown key(s) in [osg]: {', '.join(unknown)} (known: {', '.join(OSG_KEYS)})")
        return osg

    def osg_opts(self, osgb, path, out_dir, stats):
        """dmmr-osgviewer on the original model, same walkthrough and image size as the other runs.
        It renders through OSMesa whatever --backend says (OSG's fixed-function path needs a
        compatibility context; the tool has no EGL backend)."""
        opts = ["--model", osgb, "--walkthrough", path, "--out", out_dir, "--stats", stats,
                "--width", self.cfg.get("width", 512), "--height", self.cfg.get("height", 512), "--no-progress"]
        for k, v in self.osg.items():
            if isinstance(v, bool):
                v = "on" if v else "off"
            opts += [OSG_KEYS[k], v]
        return opts

    # --- a reference on every k-th frame ------------------------------------
    # Brute force costs seconds a frame at the paper's scale (4 to 12 s on 2
    # cores), so a scale may set reference_stride = k: the reference renders control points 0, k,
    # 2k, ... (one frame per control point, the same cameras), and each run's
    # frames 0, k, 2k, ... are compared with them, index for index.
    def reference_stride(self):
        k = int(self.cfg.get("reference_stride", 1))
        if k < 1:
            sys.exit("dmmr-bench: reference_stride must be at least 1")
        return k

    @classmethod
    def strided_lines(cls, path, k):
        return cls.path_lines(path)[::k]

    @staticmethod
    def csv_rows(path):
        return max(0, sum(1 for l in Path(path).read_text().splitlines() if l.strip()) - 1)

    def strided_path(self, path, k):
        if k == 1:
            return path
        sub = Path(path).with_suffix(f".every{k}.path")
        sub.write_text("\n".join(self.strided_lines(path, k)) + "\n")
        return sub

    def frames_like_reference(self, out_dir, k):
        """out_dir itself, or (k > 1) a directory of links to its frames 0, k, 2k, ... named 0, 1, 2, ..."""
        if k == 1:
            return out_dir
        d = Path(f"{out_dir}.every{k}")
        self._fresh(d)
        d.mkdir()
        frames = sorted(Path(out_dir).glob("frame_*.png"))
        for j, src in enumerate(frames[::k]):
            (d / f"frame_{j:06d}.png").symlink_to(src.resolve())
        return d

    def compare(self, ref_dir, out_dir, stride, cmp_csv):
        # thresholds are checked by the report (conservative runs must be identical)
        run_cmd([self.bin / "dmmr-compare", ref_dir, self.frames_like_reference(out_dir, stride), "--csv", cmp_csv,
                 "--min-psnr", "0", "--max-diff-pixels", "999999999"], self.log)

    def _fresh(self, *paths):
        for p in paths:
            p = Path(p)
            if p.is_dir():
                shutil.rmtree(p)
            elif p.exists():
                p.unlink()

    def run_scene(self, sc, progress):
        name = sc["name"]
        scene_dir, path, osgb = self.make_scene(sc, progress)
        rd = self.out / "runs" / name
        rd.mkdir(parents=True, exist_ok=True)
        ref_dir, ref_csv = rd / "reference", rd / "reference.csv"
        stride = self.reference_stride()
        ref_path = self.strided_path(path, stride)
        want = len(self.strided_lines(path, stride))
        if self.resume and ref_csv.exists() and self.csv_rows(ref_csv) == want:
            progress.step(f"{name}: dmmr-reference reused")
        else:
            self.missing(f"{name}'s reference run")
            # a new reference (or one of another stride): every run is compared with it again
            self._fresh(ref_dir, ref_csv, *(rd / f"{rl}.cmp.csv" for label, _, _ in self.configurations()
                                            for rl in self.run_labels(label)))
            dt = run_cmd([self.bin / "dmmr-reference", *self.common_opts(scene_dir, ref_path, ref_dir, ref_csv)],
                         self.log, env=self.env)
            self.timings[f"{name}/reference"] = dt
            progress.step(f"{name}: dmmr-reference (brute force) in {dt:.1f} s")
        osg_dir, osg_csv = rd / OSG_LABEL, rd / f"{OSG_LABEL}.csv"
        if not self.osg_baseline:
            osg_csv = None  # not run: the report says so (a CSV left from an earlier run is not used)
        elif self.resume and osg_csv.exists():
            progress.step(f"{name}: {OSG_TOOL} reused")
        else:
            self.missing(f"{name}'s {OSG_LABEL} run")
            self._fresh(osg_dir, osg_csv)
            dt = run_cmd([self.bin / OSG_TOOL, *self.osg_opts(osgb, path, osg_dir, osg_csv)], self.log, env=self.env)
            self.timings[f"{name}/{OSG_LABEL}"] = dt
            progress.step(f"{name}: {OSG_TOOL} (osgViewer + OcclusionQueryNode, original model) in {dt:.1f} s")
        configurations = {label: (n, extra) for label, n, extra in self.configurations()}
        for label, run_label in run_order(list(configurations), self.repeats):
            n, extra = configurations[label]
            self.run_render(rd, name, run_label, n, extra, scene_dir, path, ref_dir, stride, progress)
        return {"scene_dir": str(scene_dir), "walkthrough": str(path), "runs_dir": str(rd), "reference_stride": stride,
                "osg_csv": str(osg_csv) if osg_csv else None}

    def run_render(self, rd, name, label, n, extra, scene_dir, path, ref_dir, stride, progress):
        """One dmmr-render run of `n` clients into rd/label, compared with the reference."""
        out_dir, csv = rd / label, rd / f"{label}.csv"
        cmp_csv = rd / f"{label}.cmp.csv"
        if self.resume and csv.exists() and out_dir.is_dir():
            progress.step(f"{name}: {label} reused")
            if cmp_csv.exists():
                progress.step(f"{name}: {label} comparison reused")
            else:  # e.g. the reference was rerun on more frames: compare the frames kept
                self.compare(ref_dir, out_dir, stride, cmp_csv)
                progress.step(f"{name}: {label} compared with the reference")
            return
        self.missing(f"{name}'s run {label}")
        self._fresh(out_dir, csv, cmp_csv)
        cmd = [*self.render_mpi, "-np", n + 1, self.bin / "dmmr-render",
               *self.common_opts(scene_dir, path, out_dir, csv),
               "--compress", self.run_cfg.get("compress", "lz4"),
               "--client-timeout", self.run_cfg.get("client_timeout", 600), *self.render_extra, *extra]
        usage = {}
        dt = run_cmd(cmd, self.log, env=self.render_env, usage=usage)
        self.timings[f"{name}/{label}"] = dt
        self.usage[f"{name}/{label}"] = usage
        progress.step(f"{name}: dmmr-render {n} client{'s' if n > 1 else ''}"
                      f"{' ' + ' '.join(extra) if extra else ''}"
                      f"{' (' + label + ')' if '.r' in label else ''} in {dt:.1f} s")
        self.compare(ref_dir, out_dir, stride, cmp_csv)
        progress.step(f"{name}: {label} compared with the reference")
