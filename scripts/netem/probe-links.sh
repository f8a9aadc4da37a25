#!/usr/bin/env bash
# The figures of docs/netem.md: dmmr-netem-probe between rank 0 and rank 1 in
# two namespaces, unshaped and at each link setting, as a Markdown table.
# usage: scripts/netem/probe-links.sh [PROBE]   (root; default build/bin/dmmr-netem-probe)
# DMMR_NETEM_SETTINGS overrides the settings: "RATE,DELAY,JITTER;..." ("none,0,0" unshaped).
# Makes its own setup (prefix dmmrp, subnet 10.199.79) and tears it down on exit.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
probe=${1:-$here/../../build/bin/dmmr-netem-probe}
[ -x "$probe" ] || { echo "probe-links: no $probe (build first)" >&2; exit 1; }
export DMMR_NETEM_PREFIX=dmmrp DMMR_NETEM_SUBNET=10.199.79
settings=${DMMR_NETEM_SETTINGS:-"none,0,0;1gbit,0.1ms,0;100mbit,5ms,1ms;20mbit,10ms,0"}
"$here/netem.sh" down
trap '"$here/netem.sh" down' EXIT
trap 'exit 1' INT TERM
"$here/netem.sh" up 1 >&2

# busy share of the CPUs over the last second (other work on the machine inflates latency)
busy() {
  local a b
  read -r -a a < <(head -1 /proc/stat)
  sleep 1
  read -r -a b < <(head -1 /proc/stat)
  awk -v u=$((b[1] + b[2] + b[3] - a[1] - a[2] - a[3])) \
    -v t=$((b[1] + b[2] + b[3] + b[4] + b[5] + b[6] + b[7] - a[1] - a[2] - a[3] - a[4] - a[5] - a[6] - a[7])) \
    'BEGIN { printf "%.0f%%", 100 * u / t }'
}

echo "| rate | one-way delay | jitter | RTT min / median / max ms | 8 MiB s (3 runs, median) | Mbit/s | expected 8 MiB s | CPU busy before |"
echo "|---|---|---|---|---|---|---|---|"
IFS=';' read -r -a list <<<"$settings"
for s in "${list[@]}"; do
  IFS=, read -r rate delay jitter <<<"$s"
  "$here/netem.sh" shape --rate "$rate" --delay "$delay" --jitter "$jitter" >&2
  load=$(busy)
  out=$(timeout 120 "$here/mpirun-netem.sh" -- "$probe" --pings 200 --reps 3)
  v() { sed -n "s/^$1=//p" <<<"$out"; }
  expected=-
  if [ "$rate" != none ]; then
    bits=$(awk -v r="$rate" 'BEGIN { u = tolower(r); v = u + 0; sub(/^[0-9.]+/, "", u)
      printf "%.0f", v * (u == "gbit" ? 1e9 : u == "mbit" ? 1e6 : u == "kbit" ? 1e3 : 1) }')
    expected=$(awk -v b="$(v bytes)" -v r="$bits" 'BEGIN { printf "%.3f", b * 8 / r }')
  fi
  echo "| $rate | $delay | $jitter | $(v rtt_ms_min) / $(v rtt_ms_median) / $(v rtt_ms_max) |" \
    "$(v transfer_s) | $(v throughput_mbit) | $expected | $load |"
done
