#!/usr/bin/env python3
"""Markdown table for scripts/bench/cache.sh: per run, the budgets, hit rates
per level, bytes read from disk, resident maxima, median frame time, and the
worst differing pixels against the unlimited run's frames."""
import csv
import statistics
import subprocess
import sys


def mib(b):
    return f"{b / 2**20:.1f}"


def main():
    out, geometry, clients, labels = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4:]
    print(f"Scene geometry: {mib(geometry)} MiB; {clients} client(s); frame 0 (first loads) "
          "left out of the frame-time median.\n")
    print("| run | RAM budget MiB | GPU budget MiB (per context) | GPU hit rate | RAM hit rate "
          "| read from disk MiB | max RAM resident MiB | max GPU resident MiB (both contexts) "
          "| uncached draws | frame ms (median) | differing pixels vs unlimited (worst frame) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for label in labels:
        rows = list(csv.DictReader(open(f"{out}/{label}.csv")))
        def total(col):
            return sum(int(r[f"c{k}_{col}"]) for r in rows for k in range(1, clients + 1))
        def peak(col):
            return max(int(r[f"c{k}_{col}"]) for r in rows for k in range(1, clients + 1))
        gh, gm, rh, rm = total("gpu_hits"), total("gpu_misses"), total("ram_hits"), total("ram_misses")
        frame_ms = statistics.median(float(r["frame_ms"]) for r in rows[1:])
        if label == "unlimited":
            worst = "reference run"
        else:
            cmp = subprocess.run(["build/bin/dmmr-compare", f"{out}/unlimited", f"{out}/{label}",
                                  "--csv", f"{out}/{label}.cmp.csv"], capture_output=True, text=True)
            worst = max(int(r["differing_pixels"]) for r in csv.DictReader(open(f"{out}/{label}.cmp.csv")))
        budget = label.split("-")[1] if label.startswith("ram-") else None
        d = int(budget[3:]) if budget else None
        ram = mib(geometry // d) if d else "unlimited"
        gpu = mib(geometry // d // 2) if d else "unlimited"
        name = label + {"noprefetch": " (no prefetch)", "lru": " (plain LRU)",
                        "meshopt": " (meshopt-encoded scene)"}.get(label.split("-")[-1], "")
        print(f"| {name} | {ram} | {gpu} | {gh / max(1, gh + gm):.3f} | {rh / max(1, rh + rm):.3f} "
              f"| {mib(total('disk_bytes'))} | {mib(peak('ram_resident'))} | {mib(peak('gpu_resident'))} "
              f"| {total('uncached')} | {frame_ms:.1f} | {worst} |")


main()
