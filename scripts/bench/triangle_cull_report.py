#!/usr/bin/env python3
"""Markdown table from scripts/bench/triangle_cull.sh's output directory.

Frame 0 (which loads every geometry) is left out. A run's figure is its
median over frames of frame_ms (the reference's includes writing its PNG,
as dmmr-render's server writes its frame); a configuration's is the median
of its runs' figures, and a ratio is the median of the per-round ratios
(off and on ran side by side in each round). Client time is a client's own
work per frame (prepare, retrieve, load, render, read back, compress);
max/mean is over the 4 clients, per frame, then the median over frames.
"""
import csv
import os
import statistics as st
import sys

out, reps, scenes = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
WORK = ["prepare_ms", "retrieve_ms", "load_ms", "render_ms", "readback_ms", "compress_ms"]


def rows(name):
    return list(csv.DictReader(open(f"{out}/{name}.csv")))[1:]


def frame_ms(name):
    return st.median(float(x["frame_ms"]) for x in rows(name))


def client_ms(name, clients):
    """Median over frames of the mean client's work, and of max/mean."""
    mean, bal = [], []
    for x in rows(name):
        work = [sum(float(x[f"c{k}_{w}"]) for w in WORK) for k in range(1, clients + 1)]
        mean.append(sum(work) / clients)
        bal.append(max(work) / (sum(work) / clients))
    return st.median(mean), st.median(bal)


def worst_diff(name):
    return max(int(d["differing_pixels"]) for r in range(1, reps + 1)
               for d in csv.DictReader(open(f"{out}/{name}-r{r}.cmp.csv")))


def fmt(v, d=1):
    return f"{st.median(v):.{d}f} ({', '.join(f'{x:.{d}f}' for x in v)})"


R = range(1, reps + 1)
# With DMMR_BENCH_BASE, "off" is another build's default (labelled base).
OFF = os.environ.get("DMMR_BENCH_OFF_LABEL") or "off"
print(f"Median of {reps} rounds (each round's figure in brackets).\n")
print(f"| scene | reference ms | 1 client {OFF} ms | 1 client on ms | on vs {OFF} (1 client) "
      f"| reference / 1 client {OFF} | reference / 1 client on | 1 client's work {OFF} / on ms "
      f"| 4 clients {OFF} ms | 4 clients on ms | on vs {OFF} (4 clients) "
      f"| 4 clients max/mean {OFF} / on | differing pixels (worst frame) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for s in scenes:
    ref = [frame_ms(f"{s}-ref-r{r}") for r in R]
    one = {m: [frame_ms(f"{s}-1-{m}-r{r}") for r in R] for m in ("off", "on")}
    four = {m: [frame_ms(f"{s}-4-{m}-r{r}") for r in R] for m in ("off", "on")}
    work1 = {m: [client_ms(f"{s}-1-{m}-r{r}", 1)[0] for r in R] for m in ("off", "on")}
    bal4 = {m: [client_ms(f"{s}-4-{m}-r{r}", 4)[1] for r in R] for m in ("off", "on")}
    ratio = lambda a, b: [x / y for x, y in zip(a, b)]
    diff = max(worst_diff(f"{s}-{n}-{m}") for n in (1, 4) for m in ("off", "on"))
    print(f"| {s} | {fmt(ref)} | {fmt(one['off'])} | {fmt(one['on'])} "
          f"| {fmt(ratio(one['off'], one['on']), 2)}x | {fmt(ratio(ref, one['off']), 2)}x "
          f"| {fmt(ratio(ref, one['on']), 2)}x "
          f"| {st.median(work1['off']):.1f} / {st.median(work1['on']):.1f} "
          f"| {fmt(four['off'])} | {fmt(four['on'])} | {fmt(ratio(four['off'], four['on']), 2)}x "
          f"| {st.median(bal4['off']):.2f} / {st.median(bal4['on']):.2f} | {diff} |")
