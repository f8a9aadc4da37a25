#!/usr/bin/env python3
"""Markdown table from scripts/bench/clusters.sh's output directory.

Frame 0 (which loads every geometry) is left out. A run's figure is its
median over frames; a configuration's is the median of its runs' figures.
Client time is a client's own work per frame (prepare, retrieve, load,
render, read back, compress: what dmmr-bench's derived times count);
max/mean is over the 4 clients, per frame.
"""
import csv
import statistics as st
import sys

out, reps, sizes = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
WORK = ["prepare_ms", "retrieve_ms", "load_ms", "render_ms", "readback_ms", "compress_ms"]


def rows(name):
    return list(csv.DictReader(open(f"{out}/{name}.csv")))[1:]


def runs(fn):
    return [fn(r) for r in range(1, reps + 1)]


def frame_ms(name):
    return st.median(float(x["frame_ms"]) for x in rows(name))


def balance(name):
    per = []
    for x in rows(name):
        work = [sum(float(x[f"c{k}_{w}"]) for w in WORK) for k in range(1, 5)]
        per.append(max(work) / (sum(work) / 4))
    return st.median(per)


def triangles(name, clients):
    return st.median(sum(float(x[f"c{k}_triangles"]) for k in range(1, clients + 1))
                     for x in rows(name))


def worst_diff(c, k):
    return max(int(d["differing_pixels"]) for r in range(1, reps + 1)
               for d in csv.DictReader(open(f"{out}/c{c}-{k}-r{r}.cmp.csv")))


truth = list(csv.DictReader(open(f"{out}/truth.csv")))[1:]
print(f"Median over frames 1..{len(truth)}, median of {reps} runs (each run's figure in brackets).\n")
print("| cluster triangles | objects | reference ms | 1 client ms | 1 client vs reference | "
      "1 client triangles drawn | 4 clients ms | 4 clients: client time max/mean | "
      "4 clients triangles drawn (sum) | differing pixels (worst frame: ref / 1 / 4) |")
print("|---|---|---|---|---|---|---|---|---|---|")
for c in sizes:
    ref = runs(lambda r: frame_ms(f"c{c}-ref-r{r}"))
    one = runs(lambda r: frame_ms(f"c{c}-1-r{r}"))
    four = runs(lambda r: frame_ms(f"c{c}-4-r{r}"))
    bal = runs(lambda r: balance(f"c{c}-4-r{r}"))
    ratio = runs(lambda r: frame_ms(f"c{c}-ref-r{r}") / frame_ms(f"c{c}-1-r{r}"))
    objs = len(rows(f"c{c}-ref-r1")) and int(rows(f"c{c}-ref-r1")[0].get("objects", 0) or 0)
    fmt = lambda v, d=1: f"{st.median(v):.{d}f} ({', '.join(f'{x:.{d}f}' for x in v)})"
    print(f"| {c if c != '0' else '0 (whole)'} | {objs} | {fmt(ref)} | {fmt(one)} | "
          f"{fmt(ratio, 2)}x | {triangles(f'c{c}-1-r1', 1) / 1e6:.2f}M | {fmt(four)} | {fmt(bal, 2)} | "
          f"{triangles(f'c{c}-4-r1', 4) / 1e6:.2f}M | "
          f"{worst_diff(c, 'ref')} / {worst_diff(c, 1)} / {worst_diff(c, 4)} |")
vis = st.median(float(x["exact_visible_triangles"]) for x in truth)
floor = st.median(float(x["floor_ms"]) for x in truth)
print(f"\nExactly visible (reference --exact-visible on the truth run's clusters): median "
      f"{vis / 1e6:.2f}M triangles a frame; drawing them alone takes {floor:.1f} ms.")
