#!/usr/bin/env python3
"""Summarises dmmr-render statistics CSVs as Markdown (standard library only).

usage: summarize_stats.py [--label L] STATS.csv [STATS.csv ...]
Prints, per file: frames, median frame time, median cull and divide time,
divide time by objects in the frustum, load balance (max over mean of the
clients' triangles), and bytes per frame before and after compression.
"""
import csv
import statistics
import sys


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{path}: no frames")
    return rows


def clients_of(row):
    k = 0
    while f"c{k + 1}_triangles" in row:
        k += 1
    return k


def med(values):
    return statistics.median(values) if values else float("nan")


def summarize(path, label):
    rows = load(path)
    n = clients_of(rows[0])
    f = lambda r, c: float(r[c])
    balance, raw, sent = [], [], []
    for r in rows:
        tris = [f(r, f"c{k}_triangles") for k in range(1, n + 1)]
        mean = sum(tris) / n
        if mean > 0:
            balance.append(max(tris) / mean)
        raw.append(sum(f(r, f"c{k}_bytes_raw") for k in range(1, n + 1)))
        sent.append(sum(f(r, f"c{k}_bytes_sent") for k in range(1, n + 1)))
    objs = [f(r, "objects_in_frustum") for r in rows]
    div = [f(r, "divide_ms") for r in rows]
    print(f"| {label} | {n} | {len(rows)} | {med([f(r, 'frame_ms') for r in rows]):.1f} | "
          f"{med([f(r, 'cull_ms') for r in rows]):.2f} | {med(div):.2f} | "
          f"{med(objs):.0f} | {med(balance):.2f} / {max(balance):.2f} | "
          f"{med(raw) / 1024:.0f} KiB | {med(sent) / 1024:.0f} KiB ({med(raw) / max(med(sent), 1):.1f}x) |")
    return [(o, d) for o, d in zip(objs, div)]


def main(argv):
    label = None
    files = []
    i = 0
    while i < len(argv):
        if argv[i] == "--label":
            label = argv[i + 1]
            i += 2
        else:
            files.append(argv[i])
            i += 1
    print("| run | clients | frames | frame ms (median) | cull ms | divide ms | objects in frustum "
          "| balance max/mean (median / worst) | bytes raw per frame | bytes sent (ratio) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    pairs = []
    for p in files:
        pairs += summarize(p, label or p)
    # divide time against objects in the frustum, in buckets
    buckets = {}
    for o, d in pairs:  # 1-2-5 buckets: 1000+, 2000+, 5000+, 10000+, ...
        key = 0
        for e in range(0, 10):
            for m in (1, 2, 5):
                if o >= m * 10 ** e:
                    key = m * 10 ** e
        buckets.setdefault(key, []).append(d)
    print()
    print("| objects in frustum (bucket) | frames | divide ms median | divide ms max |")
    print("|---|---|---|---|")
    for k in sorted(buckets):
        v = buckets[k]
        print(f"| {k}+ | {len(v)} | {med(v):.2f} | {max(v):.2f} |")


if __name__ == "__main__":
    main(sys.argv[1:])
