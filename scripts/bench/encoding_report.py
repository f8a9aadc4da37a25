#!/usr/bin/env python3
"""Markdown table for scripts/bench/encoding.sh.

usage: encoding_report.py OUT_DIR "ENCODINGS" NAME...
Reads OUT_DIR/NAME.ENCODING.decode (codec_bench's line: encoding, files,
vertices, triangles, bytes, median seconds, triangles/s) and
OUT_DIR/NAME.ENCODING.compare.csv (dmmr-compare --csv against the float32
frames). Baseline: the indexed face set, 32 bytes per vertex and 12 per
triangle over the same unique vertices and triangles.
"""
import csv
import math
import sys


def psnr(mse):
    return math.inf if mse == 0 else 10 * math.log10(255 * 255 / mse)


def fmt_db(x):
    return "exact" if math.isinf(x) else f"{x:.1f}"


def main():
    out, encodings, names = sys.argv[1], sys.argv[2].split(), sys.argv[3:]
    print("| input | encoding | vertices | triangles | B/triangle | baseline B/triangle | "
          "ratio | decode M triangles/s | mean PSNR dB | worst PSNR dB | worst differing pixels |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in names:
        for e in encodings:
            _, files, nv, nt, size, sec, rate = open(f"{out}/{name}.{e}.decode").read().split()
            nv, nt, size, rate = int(nv), int(nt), int(size), float(rate)
            baseline = 32 * nv + 12 * nt
            rows = list(csv.DictReader(open(f"{out}/{name}.{e}.compare.csv")))
            mses = [float(r["mse"]) for r in rows]
            # Mean PSNR: of the mean squared error over all frames.
            mean = psnr(sum(mses) / len(mses))
            worst = min(psnr(m) for m in mses)
            diff = max(int(r["differing_pixels"]) for r in rows)
            print(f"| {name} | {e} | {nv:,} | {nt:,} | {size / nt:.2f} | {baseline / nt:.2f} | "
                  f"{baseline / size:.2f}x | {rate / 1e6:.1f} | {fmt_db(mean)} | {fmt_db(worst)} | "
                  f"{diff:,} |")


if __name__ == "__main__":
    main()
