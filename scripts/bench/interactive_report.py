"""Markdown for scripts/bench/interactive.sh: per scene and client count, the
walkthrough's median frame time (frames 5.., the pipeline warm) and latency,
and the pose replay's poses served against sent, pose-to-frame latency
(median, p95, each half of the run), the ratio of median latency to the
walkthrough frame time (target <= 1.5), and JPEG against PNG frames: mean
bytes and encode time.
usage: interactive_report.py OUT name|clients|in_flight..."""
import csv
import json
import statistics as st
import sys
from pathlib import Path

out, configs = Path(sys.argv[1]), [c.split("|") for c in sys.argv[2:]]
FROM = 5


def walk(tag):
    rows = list(csv.DictReader(open(out / f"{tag}-walk.csv")))[FROM:]
    return st.median(float(r["frame_ms"]) for r in rows), st.median(float(r["latency_ms"]) for r in rows)


print("| scene | clients | in flight | walkthrough frame ms | walkthrough latency ms | poses served / sent (60 Hz) | "
      "latency median ms | p95 ms | 1st half / 2nd half median ms | median latency / frame time | "
      "JPEG bytes, encode ms | PNG bytes, encode ms |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
for name, n, inflight in configs:
    frame, lat = walk(f"{name}-c{n}")
    tag = f"{name}-c{n}-f{inflight}"
    j = json.load(open(out / f"{tag}-jpeg.json"))
    p = json.load(open(out / f"{tag}-png.json"))
    jpeg = j["encodings"].get("jpeg", {})
    png = p["encodings"].get("png", {})
    print(f"| {name} | {n} | {inflight} | {frame:.1f} | {lat:.1f} | {j['poses_served']} / {j['poses_sent']} "
          f"({100 * j['poses_served'] / j['poses_sent']:.0f}%) | {j['latency_median_ms']:.1f} | "
          f"{j['latency_p95_ms']:.1f} | {j['latency_first_half_median_ms']:.1f} / "
          f"{j['latency_second_half_median_ms']:.1f} | {j['latency_median_ms'] / frame:.2f} | "
          f"{jpeg.get('bytes_mean', 0) / 1024:.1f} KiB, {jpeg.get('encode_ms_mean', 0):.2f} | "
          f"{png.get('bytes_mean', 0) / 1024:.1f} KiB, {png.get('encode_ms_mean', 0):.2f} |")
