#!/usr/bin/env python3
"""Markdown tables from scripts/bench/visibility.sh's output directory."""
import csv
import statistics as st
import sys

out, scenes = sys.argv[1], sys.argv[2:]


def rows(name):
    return list(csv.DictReader(open(f"{out}/{name}.csv")))


def med(rs, key):
    return st.median(float(r[key]) for r in rs[1:])  # frame 0 loads everything


def errors(name):
    c = list(csv.DictReader(open(f"{out}/{name}.cmp.csv")))
    ps = [float(r["psnr"]) for r in c]
    finite = [p for p in ps if p != float("inf")]
    mean = "inf" if not finite else f"{st.mean(finite):.1f}"
    worst = "inf" if not finite else f"{min(finite):.1f}"
    return mean, worst, max(int(r["differing_pixels"]) for r in c)


for s in scenes:
    ref = rows(f"ref-{s}")
    runs = {k: rows(f"{s}-{k}") for k in ("pipelined", "serial", "frustum-only")}
    pipe = runs["pipelined"]
    drawn = sum(float(r["c1_triangles"]) for r in pipe[1:])
    exact = sum(float(r["exact_visible_triangles"]) for r in ref[1:])
    frustum = sum(float(r["triangles_in_frustum"]) for r in pipe[1:])
    ratios = [float(p["c1_triangles"]) / max(float(x["exact_visible_triangles"]), 1)
              for p, x in zip(pipe[1:], ref[1:])]
    print(f"#### {s}: triangles per frame (median over frames 1..{len(pipe) - 1})\n")
    print("| scene triangles | in frustum | drawn (conservative) | exactly visible | drawn / exactly visible (sum over frames; median per frame) |")
    print("|---|---|---|---|---|")
    print(f"| {int(float(ref[0]['triangles'])):,} | {med(pipe, 'triangles_in_frustum'):,.0f} | "
          f"{med(pipe, 'c1_triangles'):,.0f} | {med(ref, 'exact_visible_triangles'):,.0f} | "
          f"{drawn / max(exact, 1):.2f}; {st.median(ratios):.2f} |")
    print(f"\n#### {s}: frame time, 1 client (median ms over frames 1..{len(pipe) - 1})\n")
    print("| run | frame ms | vs reference | prepare | retrieve | pass | render | queries | visible | differing pixels (worst frame) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    r0 = med(ref, "frame_ms")
    print(f"| dmmr-reference (brute force) | {r0:.1f} | 1.00x | | | | | | | reference |")
    for k, rs in runs.items():
        f = med(rs, "frame_ms")
        print(f"| dmmr-render, {k} | {f:.1f} | {r0 / f:.2f}x faster | {med(rs, 'c1_prepare_ms'):.1f} | "
              f"{med(rs, 'c1_retrieve_ms'):.1f} | {med(rs, 'c1_pass_ms'):.1f} | {med(rs, 'c1_render_ms'):.1f} | "
              f"{med(rs, 'c1_queried'):.0f} | {med(rs, 'c1_visible'):.0f} | {errors(s + '-' + k)[2]} |")
    print(f"\n#### {s}: speed against error (visibility settings)\n")
    print("| query threshold (samples: pixels of the box's front faces) | keep frames | frame ms | triangles drawn | mean PSNR dB | worst PSNR dB | worst differing pixels |")
    print("|---|---|---|---|---|---|---|")
    for t in (0, 16, 64):
        for k in (0, 3, 10):
            rs = rows(f"{s}-t{t}-k{k}")
            mean, worst, diff = errors(f"{s}-t{t}-k{k}")
            print(f"| {t} | {k} | {med(rs, 'frame_ms'):.1f} | {med(rs, 'c1_triangles'):,.0f} | {mean} | {worst} | {diff} |")
    for label, t in (("lod", 0), ("lod-t16", 16)):
        rs = rows(f"{s}-{label}")
        mean, worst, diff = errors(f"{s}-{label}")
        print(f"| {t}, occluder LOD | 0 | {med(rs, 'frame_ms'):.1f} | {med(rs, 'c1_triangles'):,.0f} | {mean} | {worst} | {diff} |")
    print()
