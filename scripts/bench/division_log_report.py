#!/usr/bin/env python3
"""How well the division's inputs predict a client's time: reads division logs
(dmmr-render --division-log) and, per log, fits a non-negative linear model of
the client's time (the log's `ms`) to two sets of inputs, frames 1.. (frame 0
fills the caches):

- the client's own counts, known only afterwards (hindsight): objects drawn,
  triangles, objects tested, pixels, fill;
- the server's forecast at plan time, what the division can use: objects in
  the region's list, those drawn lately, their triangles, pixels, their fill.

For each it gives R^2 (over all client-frames) and the median over frames of
max/mean of measured time over predicted time: the imbalance that would be
left if the division balanced that prediction exactly. Beside them the
measured max/mean and the planned weights' max/mean (how evenly the division
split what it was given).
usage: division_log_report.py LABEL=LOG.csv [FEATURE_SET=col,col ...] ...
  extra feature sets are fitted too (columns of the log).
Needs numpy (Debian python3-numpy, which python3-matplotlib of install-deps.sh brings;
/usr/bin/python3).
"""
import csv
import statistics
import sys

import numpy as np

HINDSIGHT = ["drawn", "triangles", "tested", "pixels", "fill"]
FORECAST = ["objects", "drawn_lately", "triangles_lately", "pixels", "fill_lately"]


def nnls(a, y, rounds=60):
    """Least squares with every coefficient >= 0 (active-set, Lawson-Hanson)."""
    n = a.shape[1]
    passive = np.zeros(n, bool)
    x = np.zeros(n)
    for _ in range(rounds):
        w = a.T @ (y - a @ x)
        free = ~passive & (w > 1e-12)
        if not free.any():
            break
        passive[np.argmax(np.where(free, w, -np.inf))] = True
        while True:
            z = np.zeros(n)
            z[passive] = np.linalg.lstsq(a[:, passive], y, rcond=None)[0]
            if (z[passive] > 0).all():
                x = z
                break
            neg = passive & (z <= 0)
            alpha = np.min(x[neg] / (x[neg] - z[neg]))
            x = x + alpha * (z - x)
            passive &= x > 1e-15
    return x


def per_frame_max_mean(rows, values):
    frames = {}
    for r, v in zip(rows, values):
        frames.setdefault(r["frame"], []).append(v)
    return statistics.median(max(v) / (sum(v) / len(v)) for v in frames.values() if sum(v) > 0)


def fit(rows, cols):
    a = np.array([[float(r[c]) for c in cols] for r in rows])
    y = np.array([float(r["ms"]) for r in rows])
    scale = a.max(axis=0)
    scale[scale == 0] = 1
    coef = nnls(a / scale, y) / scale
    pred = a @ coef
    r2 = 1 - ((y - pred) ** 2).sum() / ((y - y.mean()) ** 2).sum()
    left = per_frame_max_mean(rows, [yi / max(p, 1e-9) for yi, p in zip(y, pred)])
    return r2, left, coef


def main(argv):
    logs = [a.split("=", 1) for a in argv if a.endswith(".csv")]
    extra = [a.split("=", 1) for a in argv if not a.endswith(".csv")]
    sets = [("hindsight", HINDSIGHT), ("forecast", FORECAST)] + [(k, v.split(",")) for k, v in extra]
    head = "| log | client-frames | measured max/mean | planned max/mean |"
    line = "|---|---|---|---|"
    for name, _ in sets:
        head += f" {name} R^2 | left max/mean ({name}) |"
        line += "---|---|"
    print(head)
    print(line)
    coefs = []
    for label, path in logs:
        rows = [r for r in csv.DictReader(open(path)) if int(r["frame"]) >= 1]
        ms = [float(r["ms"]) for r in rows]
        out = f"| {label} | {len(rows)} | {per_frame_max_mean(rows, ms):.2f} | "
        out += f"{per_frame_max_mean(rows, [float(r['planned']) for r in rows]):.2f} |"
        for name, cols in sets:
            r2, left, coef = fit(rows, cols)
            out += f" {r2:.2f} | {left:.2f} |"
            coefs.append(f"{label} {name}: " + ", ".join(
                f"{c} {k * 1e6:.3g} ns" for c, k in zip(cols, coef)))
        print(out)
    print()
    for c in coefs:
        print(f"- {c}")


if __name__ == "__main__":
    main(sys.argv[1:])
