#!/usr/bin/env bash
# CTest netem_shaping (labels netem, mpi): shaping takes effect. Brings up two
# namespaces (scripts/netem/netem.sh, its own prefix and subnet, so a benchmark's
# setup is never touched), runs dmmr-netem-probe between them over MPI/TCP
# unshaped and then at 100 Mbit/s with 5 ms one-way delay, and checks:
#   - rank 0 and rank 1 ran in namespaces 0 and 1;
#   - the smallest 1-byte round trip is at least 2 x 5 ms (every packet is
#     delayed, so nothing can be faster) and at most 2 x 5 ms + 2 ms; the median
#     at most 2 x 5 ms + 8 ms (ranks busy-poll and share two cores with whatever
#     else runs, so single round trips can be late, never early);
#   - 8 MiB take between 0.95 and 1.5 times 8 MiB / 100 Mbit/s (0.671 s; Ethernet,
#     IP and TCP headers add 4.6 %, slow start a few round trips), and the
#     unshaped transfer took under a quarter of that;
#   - the receiver's bridge port (tbf) passed at least 8 MiB.
# Exits 77 (skipped), saying why, only when the prerequisites are absent: not
# root, no mpirun, or no network namespaces here (netem.sh check exits 77: no
# iproute2, or ip netns add fails, as in an unprivileged container). Where
# namespaces work, as on CI's machine as root, everything else is checked: a
# kernel that cannot shape a link (netem.sh check exits 1) fails the test.
# usage: netem_test.sh PROBE [DELAYD]
set -euo pipefail
probe=${1:?usage: netem_test.sh PROBE [DELAYD]}
[ -n "${2:-}" ] && export DMMR_NETEM_DELAYD=$2
here=$(cd "$(dirname "$0")" && pwd)
netem=$here/../../scripts/netem/netem.sh
run=$here/../../scripts/netem/mpirun-netem.sh
export DMMR_NETEM_PREFIX=dmmrt DMMR_NETEM_SUBNET=10.199.78

if [ "$(id -u)" -ne 0 ]; then
  echo "SKIP: not root (network namespaces need root)"
  exit 77
fi
command -v mpirun >/dev/null || { echo "SKIP: no mpirun"; exit 77; }
rc=0
"$netem" check || rc=$?
case $rc in
  0) ;;
  77)
    echo "SKIP: no network namespaces here (netem.sh check, above, says why)"
    exit 77
    ;;
  *)
    echo "FAIL: netem.sh check exited $rc: namespaces work, but a link cannot be shaped (above)"
    exit 1
    ;;
esac

"$netem" down # a setup left by a killed earlier run of this test
trap '"$netem" down' EXIT
trap 'exit 1' INT TERM

fail=0
check() { # check DESCRIPTION AWK-CONDITION
  if awk "BEGIN { exit !($2) }"; then
    echo "ok:   $1"
  else
    echo "FAIL: $1"
    fail=1
  fi
}
val() { sed -n "s/^$1=//p" "$2"; }

out=$(mktemp -d)
"$netem" up 1
timeout 60 "$run" -- "$probe" --pings 20 --reps 1 | tee "$out/unshaped.txt"

rate_mbit=100 delay_ms=5 bytes=$((8 << 20))
"$netem" shape --rate ${rate_mbit}mbit --delay ${delay_ms}ms
timeout 60 "$run" -- "$probe" --pings 50 --reps 3 --bytes $bytes | tee "$out/shaped.txt"
sent=$(tc -s qdisc show dev dmmrt-h1 | awk '/Sent/ {print $2; exit}')

s=$out/shaped.txt u=$out/unshaped.txt
expected=$(awk "BEGIN { print $bytes * 8 / ($rate_mbit * 1e6) }")
echo "expected: one-way ${delay_ms} ms, round trip $((2 * delay_ms)) ms, 8 MiB in ${expected} s"
check "rank 0 in dmmrt-ns0, rank 1 in dmmrt-ns1" \
  "\"$(val rank0 "$s")\" == \"dmmrt-ns0\" && \"$(val rank1 "$s")\" == \"dmmrt-ns1\""
check "min round trip $(val rtt_ms_min "$s") ms within [10, 12] ms" \
  "$(val rtt_ms_min "$s") >= 2 * $delay_ms - 0.05 && $(val rtt_ms_min "$s") <= 2 * $delay_ms + 2"
check "median round trip $(val rtt_ms_median "$s") ms within [10, 18] ms" \
  "$(val rtt_ms_median "$s") >= 2 * $delay_ms - 0.05 && $(val rtt_ms_median "$s") <= 2 * $delay_ms + 8"
check "8 MiB in $(val transfer_s "$s") s, within [0.95, 1.5] x $expected s" \
  "$(val transfer_s "$s") >= 0.95 * $expected && $(val transfer_s "$s") <= 1.5 * $expected"
check "unshaped 8 MiB in $(val transfer_s "$u") s, under a quarter of shaped" \
  "$(val transfer_s "$u") < 0.25 * $(val transfer_s "$s")"
check "unshaped round trip $(val rtt_ms_min "$u") ms under 1 ms" "$(val rtt_ms_min "$u") < 1"
check "bridge port to rank 1 passed ${sent:-0} bytes through tbf, at least 3 x 8 MiB" \
  "${sent:-0} >= 3 * $bytes"
rm -rf "$out"
exit $fail
