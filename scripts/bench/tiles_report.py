#!/usr/bin/env python3
"""Markdown tables for scripts/bench/tiles.sh: frame distribution strategies on
emulated networks, efficiency, the tile-size sweep, and exactness.

Measured: the median over frames 1.. of the server's frame_ms (wall time
between assembled frames) under the emulated link, all ranks sharing this
machine's cores. Derived: per frame, server culling and division plus the
slowest client's own work (prepare, retrieve, load, render, read back,
compress, summed over its tiles) -- what a cluster with a machine per client
would need without any network at all."""
import argparse
import csv
import statistics
import sys
from pathlib import Path

WORK = ["prepare_ms", "retrieve_ms", "load_ms", "render_ms", "readback_ms", "compress_ms"]
STRATEGIES = [("frustum", "frustum division"), ("static", "tiles-static"),
              ("dynamic", "tiles-dynamic, 2 in flight"), ("dynamic1", "tiles-dynamic, 1 in flight")]
NET_NAMES = {"lan": "LAN 1 Gbit/s, 0.1 ms", "wifi": "100 Mbit/s, 5 ms +- 1 ms",
             "slow": "20 Mbit/s, 10 ms +- 2 ms"}


def load(out, name, clients):
    path = out / f"{name}.csv"
    if not path.exists():
        return None
    rows = list(csv.DictReader(path.open()))[1:]  # frame 0 loads geometry
    if not rows:
        return None
    measured = statistics.median(float(r["frame_ms"]) for r in rows)
    derived = statistics.median(
        float(r["cull_ms"]) + float(r["divide_ms"]) +
        max(sum(float(r[f"c{k}_{c}"]) for c in WORK) for k in range(1, clients + 1))
        for r in rows)
    sent = statistics.median(sum(float(r[f"c{k}_bytes_sent"]) for k in range(1, clients + 1))
                             for r in rows)
    worst = 0
    cmp_path = out / f"{name}.cmp.csv"
    if cmp_path.exists():
        for r in csv.DictReader(cmp_path.open()):
            worst = max(worst, int(r["differing_pixels"]))
    else:
        worst = None
    return {"measured": measured, "derived": derived, "sent": sent, "worst": worst}


def fmt(x, digits=1):
    return "" if x is None else f"{x:.{digits}f}"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--scenes", default="plant1m monument1m")
    ap.add_argument("--clients", default="1 2 4 8 16")
    ap.add_argument("--nets", default="lan wifi slow")
    ap.add_argument("--tile", default="64x64")
    ap.add_argument("--sweep-tiles", default="32x32 64x64 128x128 256x256")
    ap.add_argument("--sweep-clients", default="4")
    ap.add_argument("--sweep-net", default="wifi")
    a = ap.parse_args()
    out = Path(a.out)
    scenes, nets = a.scenes.split(), a.nets.split()
    clients = [int(c) for c in a.clients.split()]
    worst_all = 0
    runs = 0

    for s in scenes:
        res = {}
        for net in nets:
            for key, _ in STRATEGIES:
                for n in clients:
                    r = load(out, f"{s}-{net}-c{n}-{key}", n)
                    if r:
                        res[(net, key, n)] = r
                        runs += 1
                        if r["worst"] is not None:
                            worst_all = max(worst_all, r["worst"])
        print(f"#### {s}: frame time, measured under the emulated link (median ms, frames 1..)\n")
        print("| network | strategy | " + " | ".join(f"{n} client{'s' if n > 1 else ''}" for n in clients) + " |")
        print("|---|---|" + "---|" * len(clients))
        for net in nets:
            for key, label in STRATEGIES:
                cells = [fmt(res[(net, key, n)]["measured"]) if (net, key, n) in res else "" for n in clients]
                print(f"| {NET_NAMES.get(net, net)} | {label} | " + " | ".join(cells) + " |")
        print()
        print(f"#### {s}: efficiency tau_1 / (S tau_S), measured (derived in brackets)\n")
        print("| network | strategy | " + " | ".join(f"S={n}" for n in clients) + " |")
        print("|---|---|" + "---|" * len(clients))
        for net in nets:
            for key, label in STRATEGIES:
                base = res.get((net, key, clients[0]))
                cells = []
                for n in clients:
                    r = res.get((net, key, n))
                    if not base or not r:
                        cells.append("")
                        continue
                    s_ratio = n / clients[0]
                    cells.append(f"{base['measured'] / (s_ratio * r['measured']):.2f} "
                                 f"({base['derived'] / (s_ratio * r['derived']):.2f})")
                print(f"| {NET_NAMES.get(net, net)} | {label} | " + " | ".join(cells) + " |")
        print()
        print(f"#### {s}: tiles-static against tiles-dynamic (2 in flight), measured frame time ratio "
              "dynamic / static (above 1: static wins)\n")
        print("| network | " + " | ".join(f"S={n}" for n in clients) + " |")
        print("|---|" + "---|" * len(clients))
        for net in nets:
            cells = []
            for n in clients:
                st, dy = res.get((net, "static", n)), res.get((net, "dynamic", n))
                cells.append(f"{dy['measured'] / st['measured']:.2f}" if st and dy else "")
            print(f"| {NET_NAMES.get(net, net)} | " + " | ".join(cells) + " |")
        print()

    sweep_n = int(a.sweep_clients)
    print(f"#### Tile size: {sweep_n} clients, {NET_NAMES.get(a.sweep_net, a.sweep_net)} "
          "(median ms, measured; derived in brackets)\n")
    print("| tile | " + " | ".join(f"{s} static | {s} dynamic" for s in scenes) + " |")
    print("|---|" + "---|---|" * len(scenes))
    for t in a.sweep_tiles.split():
        cells = []
        for s in scenes:
            for key in ("static", "dynamic"):
                r = load(out, f"{s}-{a.sweep_net}-c{sweep_n}-{key}-{t}", sweep_n)
                if r:
                    runs += 1
                    if r["worst"] is not None:
                        worst_all = max(worst_all, r["worst"])
                cells.append(f"{fmt(r['measured'])} ({fmt(r['derived'])})" if r else "")
        print(f"| {t} | " + " | ".join(cells) + " |")
    print()
    print(f"Exactness: {runs} runs, worst differing pixels in any frame against dmmr-reference: "
          f"{worst_all}.")
    return 0 if worst_all == 0 else 2


if __name__ == "__main__":
    sys.exit(main())
