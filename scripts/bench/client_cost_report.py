#!/usr/bin/env python3
"""Markdown tables from scripts/bench/client_cost.sh's output directory.

Frame 0 (which loads every geometry) is left out. A run's figure is its
median over frames; a configuration's is the median of its runs' figures.
"""
import csv
import os
import statistics as st
import sys

out, reps, scenes = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
CONFIGS = ["base", "queries-split", "pyramid-split", "pyramid-split-nocost", "pyramid-fused", "pyramid-fused-predict", "pyramid-fused-nopredict", "pyramid-fused-noparts", "pyramid-fused-wholedraws", "pyramid-fused-nocost", "auto", "off"]
STAGES = ["prepare_ms", "retrieve_ms", "render_ms", "readback_ms", "compress_ms"]


def rows(name):
    return list(csv.DictReader(open(f"{out}/{name}.csv")))[1:]


def med(rs, key):
    return st.median(float(r[key]) for r in rs)


def over_runs(scene, label, key, prefix=""):
    return st.median(med(rows(f"{scene}-{label}-r{r}"), prefix + key) for r in range(1, reps + 1))


def worst_diff(scene, label):
    return max(int(d["differing_pixels"]) for r in range(1, reps + 1)
               for d in csv.DictReader(open(f"{out}/{scene}-{label}-r{r}.cmp.csv")))


for s in scenes:
    exact = rows(f"{s}-exact")
    ref = over_runs(s, "ref", "frame_ms")
    refs = [med(rows(f"{s}-ref-r{r}"), "frame_ms") for r in range(1, reps + 1)]
    print(f"#### {s} (median ms per frame over frames 1..{len(exact)}, median of {reps} runs)\n")
    print(f"dmmr-reference: {ref:.1f} ms (runs: {', '.join(f'{x:.1f}' for x in refs)}); "
          f"fill-rate floor (the exactly visible set alone, drawn and read back): "
          f"{med(exact, 'floor_ms'):.1f} ms; exactly visible: {med(exact, 'exact_visible_objects'):.0f} "
          f"objects, {med(exact, 'exact_visible_triangles'):,.0f} triangles\n")
    print("| run | frame ms | vs reference | prepare | retrieve | render | readback | compress | "
          "render thread CPU | tested | visible | triangles drawn | drawn / exactly visible | "
          "worst differing pixels |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    ev = sum(float(r["exact_visible_triangles"]) for r in exact)
    for c in CONFIGS:
        if not os.path.exists(f"{out}/{s}-{c}-r1.csv"):  # left out (DMMR_BENCH_CONFIGS)
            continue
        f = over_runs(s, c, "frame_ms")
        drawn = st.median(sum(float(x["c1_triangles"]) for x in rows(f"{s}-{c}-r{r}"))
                          for r in range(1, reps + 1))
        stages = " | ".join(f"{over_runs(s, c, k, 'c1_'):.1f}" for k in STAGES)
        cpu = over_runs(s, c, "render_cpu_ms", "c1_")
        print(f"| {c} | {f:.1f} | {ref / f:.2f}x | {stages} | {cpu:.1f} | "
              f"{over_runs(s, c, 'queried', 'c1_'):.0f} | "
              f"{over_runs(s, c, 'visible', 'c1_'):.0f} | {over_runs(s, c, 'triangles', 'c1_'):,.0f} | "
              f"{drawn / max(ev, 1):.2f} | {worst_diff(s, c)} |")
    print()
