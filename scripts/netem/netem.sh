#!/usr/bin/env bash
# Emulated cluster network on one machine (docs/netem.md): N+1 network
# namespaces PREFIX-ns0..PREFIX-nsN (rank k runs in namespace k, address
# SUBNET.(k+1)), each joined by a veth pair to a bridge PREFIX-br in the root
# namespace (address SUBNET.254, so mpirun there reaches its daemons), every
# link shaped with tc. Needs root.
#
#   netem.sh check                  what this kernel offers; exit 0 when a link can be
#                                   shaped (rate and delay); 77 (CTest's skip code) when
#                                   namespaces are out of reach (not root, no iproute2,
#                                   ip netns add fails); 1 when they work but a link
#                                   cannot be shaped (no bridge, tbf, or netem/nfqueue)
#   netem.sh up N [SHAPE...]        make namespaces 0..N (refuses when PREFIX is up already)
#   netem.sh shape [SHAPE...]       reshape the links of what is up (no namespace remade)
#   netem.sh down                   tear everything of PREFIX down; idempotent, never fails
#   netem.sh status                 the setup and every qdisc
#   netem.sh exec K CMD...          run CMD in namespace K
#   netem.sh hosts                  the namespaces' addresses, rank order, one per line
#
# SHAPE: --rate RATE (tc units: 1gbit, 100mbit, 20mbit; "none" = unlimited; default none)
#        --delay DELAY (one way: 0.1ms, 5ms, 100us; default 0)
#        --jitter J (uniform in [-J, +J]; default 0)
#        --queue LAT (tbf queue, as time at RATE; default 50ms)
#        --method auto|netem|nfqueue (how delay is made; default auto: netem when the
#                                     kernel has sch_netem, else nfqueue)
# What a link does: every packet a namespace sends is rate-limited at RATE (tbf on its
# eth0), every packet it receives is rate-limited at RATE too (tbf on the bridge port:
# full-duplex NICs on an ideal switch), and every packet gets DELAY +- JITTER once on its
# way. Delay method netem: netem on the sender's eth0, tbf as its child. Method nfqueue
# (kernels without sch_netem): an iptables NFQUEUE rule on the receiver's PREROUTING and
# dmmr-netem-delayd (tests/netem/netem_delayd.cpp) in that namespace holding each packet
# (jitter never reorders there). Delay is applied where the packet is received because a
# packet held on the sender side still counts against TCP small queues, which would cap
# a stream at a few packets per delay.
#
# Environment: DMMR_NETEM_PREFIX (default dmmr; at most 8 characters),
# DMMR_NETEM_SUBNET (first three octets of a /24, default 10.199.77),
# DMMR_NETEM_DELAYD (the delay daemon; default build/bin/dmmr-netem-delayd, else it is
# compiled from tests/netem/netem_delayd.cpp into the state directory).
# State: /run/PREFIX-netem/ (config, pids, logs).
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
prefix=${DMMR_NETEM_PREFIX:-dmmr}
subnet=${DMMR_NETEM_SUBNET:-10.199.77}
state=/run/$prefix-netem
bridge=$prefix-br

die() {
  echo "netem: $*" >&2
  exit 1
}
[ ${#prefix} -le 8 ] || die "DMMR_NETEM_PREFIX '$prefix' is longer than 8 characters"
[[ $subnet =~ ^[0-9]+\.[0-9]+\.[0-9]+$ ]] || die "DMMR_NETEM_SUBNET '$subnet' is not three octets"

ns() { echo "$prefix-ns$1"; }
addr() { echo "$subnet.$(($1 + 1))"; }

# "100mbit" -> bits per second (tc's units; "bps" suffixes are bytes per second)
rate_bits() {
  awk -v r="$1" 'BEGIN {
    if (!match(tolower(r), /^[0-9.]+/)) exit 1
    v = substr(r, 1, RLENGTH); u = tolower(substr(r, RLENGTH + 1))
    m["bit"] = 1; m["kbit"] = 1e3; m["mbit"] = 1e6; m["gbit"] = 1e9
    m["bps"] = 8; m["kbps"] = 8e3; m["mbps"] = 8e6; m["gbps"] = 8e9
    m["kibit"] = 1024; m["mibit"] = 1048576; m["gibit"] = 1073741824
    if (!(u in m) || v <= 0) exit 1
    printf "%.0f\n", v * m[u] }'
}
# "5ms" -> microseconds
time_us() {
  awk -v t="$1" 'BEGIN {
    if (!match(tolower(t), /^[0-9.]+/)) exit 1
    v = substr(t, 1, RLENGTH); u = tolower(substr(t, RLENGTH + 1))
    m[""] = 1; m["us"] = 1; m["usec"] = 1; m["ms"] = 1e3; m["msec"] = 1e3; m["s"] = 1e6; m["sec"] = 1e6
    if (!(u in m)) exit 1
    printf "%.0f\n", v * m[u] }'
}

# Probes in a throwaway namespace; sets have_netem, have_tbf, have_nfqueue, why_*.
probe_kernel() {
  local t=$prefix-probe$$
  have_netns=0 have_netem=0 have_tbf=0 have_nfqueue=0 have_bridge=0
  why_netns="" why_netem="" why_tbf="" why_nfqueue="" why_bridge=""
  if ! why_netns=$(ip netns add "$t" 2>&1); then
    return
  fi
  have_netns=1
  ip -n "$t" link add p0 type veth peer name p1 >/dev/null 2>&1 || true
  if why_netem=$(ip netns exec "$t" tc qdisc add dev p0 root netem delay 1ms 2>&1); then
    have_netem=1
    ip netns exec "$t" tc qdisc del dev p0 root >/dev/null 2>&1 || true
  fi
  if why_tbf=$(ip netns exec "$t" tc qdisc add dev p0 root tbf rate 10mbit burst 4kb latency 10ms 2>&1); then
    have_tbf=1
  fi
  if ! command -v iptables >/dev/null; then
    why_nfqueue="no iptables command (apt-get install iptables)"
  elif why_nfqueue=$(ip netns exec "$t" iptables -t mangle -A PREROUTING -i p0 -j NFQUEUE --queue-num 0 2>&1); then
    have_nfqueue=1
  fi
  if why_bridge=$(ip -n "$t" link add b0 type bridge 2>&1); then have_bridge=1; fi
  ip netns del "$t" >/dev/null 2>&1 || true
}

cmd_check() {
  if [ "$(id -u)" -ne 0 ]; then
    echo "netem: not root: no namespaces"
    exit 77
  fi
  command -v ip >/dev/null || { echo "netem: no ip command (iproute2)"; exit 77; }
  command -v tc >/dev/null || { echo "netem: no tc command (iproute2)"; exit 77; }
  probe_kernel
  if [ $have_netns -eq 0 ]; then
    echo "netem: ip netns add fails: $why_netns"
    exit 77
  fi
  echo "netns: yes"
  [ $have_bridge -eq 1 ] && echo "bridge: yes" || echo "bridge: no ($why_bridge)"
  [ $have_tbf -eq 1 ] && echo "tbf (rate): yes" || echo "tbf (rate): no ($why_tbf)"
  [ $have_netem -eq 1 ] && echo "netem (delay): yes" || echo "netem (delay): no ($why_netem)"
  [ $have_nfqueue -eq 1 ] && echo "nfqueue (delay fallback): yes" || echo "nfqueue (delay fallback): no ($why_nfqueue)"
  if [ $have_bridge -eq 1 ] && [ $have_tbf -eq 1 ] && { [ $have_netem -eq 1 ] || [ $have_nfqueue -eq 1 ]; }; then
    [ $have_netem -eq 1 ] && echo "delay method: netem" || echo "delay method: nfqueue (dmmr-netem-delayd)"
    exit 0
  fi
  echo "netem: cannot emulate a link here (needs bridge, tbf, and netem or nfqueue)"
  exit 1
}

# The delay daemon's binary, compiled into the state directory when no build has one.
delayd_bin() {
  local b=${DMMR_NETEM_DELAYD:-$root/build/bin/dmmr-netem-delayd}
  local src=$root/tests/netem/netem_delayd.cpp
  if [ -x "$b" ]; then
    echo "$b"
    return
  fi
  b=$state/dmmr-netem-delayd
  if [ ! -x "$b" ] || [ "$src" -nt "$b" ]; then
    "${CXX:-c++}" -std=c++20 -O2 -o "$b" "$src" >&2 || die "cannot compile $src"
  fi
  echo "$b"
}

# Parses SHAPE options into rate, delay, jitter, queue, method.
parse_shape() {
  rate=none delay=0 jitter=0 queue=50ms method=auto
  while [ $# -gt 0 ]; do
    case $1 in
      --rate) rate=$2; shift 2 ;;
      --delay) delay=$2; shift 2 ;;
      --jitter) jitter=$2; shift 2 ;;
      --queue) queue=$2; shift 2 ;;
      --method) method=$2; shift 2 ;;
      *) die "unknown option '$1' (SHAPE: --rate --delay --jitter --queue --method)" ;;
    esac
  done
  delay_us=$(time_us "$delay") || die "bad --delay '$delay'"
  jitter_us=$(time_us "$jitter") || die "bad --jitter '$jitter'"
  queue_us=$(time_us "$queue") || die "bad --queue '$queue'"
  if [ "$rate" = none ]; then
    rate_bps=0
  else
    rate_bps=$(rate_bits "$rate") || die "bad --rate '$rate'"
  fi
  case $method in auto | netem | nfqueue) ;; *) die "bad --method '$method'" ;; esac
}

# tbf_on NS DEV [PARENT_HANDLE]: tbf on DEV in namespace NS ("" = root namespace), at the
# root or as child 10: of PARENT_HANDLE. Burst: 1 ms at the rate, at least two full frames
# (tbf drops packets larger than its burst and splits GSO packets larger than it).
tbf_on() {
  local nsarg=() dev=$2 where=(root)
  [ -n "$1" ] && nsarg=(-n "$1")
  [ -n "${3:-}" ] && where=(parent "$3" handle 10:)
  local burst=$((rate_bps / 8 / 1000))
  [ $burst -lt 3028 ] && burst=3028
  local limit=$((rate_bps * queue_us / 8000000 + burst))
  tc "${nsarg[@]}" qdisc replace dev "$dev" "${where[@]}" tbf rate "${rate_bps}bit" \
    burst "$burst" limit "$limit"
}

stop_daemons() {
  local f pid
  for f in "$state"/delayd-*.ready; do
    [ -f "$f" ] || continue
    pid=$(awk '{print $2}' "$f")
    # only our daemon: its command line names this ready file
    if [ -n "$pid" ] && tr '\0' ' ' <"/proc/$pid/cmdline" 2>/dev/null | grep -qF -- "--ready $f"; then
      kill -TERM "$pid" 2>/dev/null || true
      # gone or a zombie (whoever adopted it may reap it late)
      for _ in $(seq 50); do
        [ "$(awk '{print $3}' "/proc/$pid/stat" 2>/dev/null || echo Z)" = Z ] && break
        sleep 0.02
      done
    fi
    rm -f "$f"
  done
}

# (Re)applies the shaping in $state/config to every link.
apply_shape() {
  local n k nsk
  n=$(cat "$state/n")
  if [ "$method" = auto ]; then
    probe_kernel
    if [ $have_netem -eq 1 ]; then
      method=netem
    else
      method=nfqueue
      [ "$delay_us" -gt 0 ] && echo "netem: no sch_netem in this kernel ($why_netem); delay by NFQUEUE and dmmr-netem-delayd, rate by tbf" >&2
    fi
  fi
  if [ "$method" = nfqueue ] && [ "$delay_us" -gt 0 ]; then
    local d
    d=$(delayd_bin)
  fi
  stop_daemons
  for k in $(seq 0 "$n"); do
    nsk=$(ns "$k")
    tc -n "$nsk" qdisc del dev eth0 root >/dev/null 2>&1 || true
    tc qdisc del dev "$prefix-h$k" root >/dev/null 2>&1 || true
    ip netns exec "$nsk" iptables -t mangle -F PREROUTING >/dev/null 2>&1 || true
    # sending side: [netem delay ->] tbf rate
    if [ "$method" = netem ] && [ "$delay_us" -gt 0 ]; then
      local jit=()
      [ "$jitter_us" -gt 0 ] && jit=("${jitter_us}us")
      tc -n "$nsk" qdisc add dev eth0 root handle 1: netem delay "${delay_us}us" "${jit[@]}" limit 100000
      [ "$rate_bps" -gt 0 ] && tbf_on "$nsk" eth0 1:
    elif [ "$rate_bps" -gt 0 ]; then
      tbf_on "$nsk" eth0
    fi
    # receiving side: tbf on the bridge port, [nfqueue delay in the namespace]
    [ "$rate_bps" -gt 0 ] && tbf_on "" "$prefix-h$k"
    if [ "$method" = nfqueue ] && [ "$delay_us" -gt 0 ]; then
      ip netns exec "$nsk" iptables -t mangle -A PREROUTING -i eth0 -j NFQUEUE --queue-num 0
      rm -f "$state/delayd-$k.ready"
      ip netns exec "$nsk" "$d" --delay-us "$delay_us" --jitter-us "$jitter_us" --seed $((k + 1)) \
        --ready "$state/delayd-$k.ready" </dev/null >>"$state/delayd-$k.log" 2>&1 &
    fi
  done
  if [ "$method" = nfqueue ] && [ "$delay_us" -gt 0 ]; then
    for k in $(seq 0 "$n"); do
      for _ in $(seq 250); do [ -s "$state/delayd-$k.ready" ] && break; sleep 0.02; done
      [ -s "$state/delayd-$k.ready" ] || die "delay daemon in $(ns "$k") did not start: $(tail -3 "$state/delayd-$k.log")"
    done
  fi
  cat >"$state/config" <<EOF
n=$n
subnet=$subnet
rate=$rate
rate_bps=$rate_bps
delay_us=$delay_us
jitter_us=$jitter_us
queue_us=$queue_us
method=$method
EOF
  echo "netem: $((n + 1)) namespaces $(ns 0)..$(ns "$n") on $subnet.0/24: rate $rate, delay ${delay_us} us," \
    "jitter ${jitter_us} us, queue ${queue_us} us, delay by $([ "$delay_us" -gt 0 ] && echo "$method" || echo none)"
}

cmd_up() {
  [ $# -ge 1 ] || die "usage: netem.sh up N [SHAPE...]"
  local n=$1
  shift
  if ! [[ $n =~ ^[0-9]+$ ]] || [ "$n" -lt 1 ] || [ "$n" -gt 252 ]; then die "N must be 1..252"; fi
  parse_shape "$@"
  [ "$(id -u)" -eq 0 ] || die "needs root"
  if [ -e "$state" ] || ip link show "$bridge" >/dev/null 2>&1; then
    die "$prefix is up already (netem.sh down first, or set DMMR_NETEM_PREFIX)"
  fi
  if [ -n "$(ip route show "$subnet.0/24" 2>/dev/null)" ] || ip -o addr show | grep -qF " $subnet.254/"; then
    die "$subnet.0/24 is in use in the root namespace (set DMMR_NETEM_SUBNET)"
  fi
  mkdir -p "$state"
  set -E
  trap 'echo "netem: up failed; tearing down what it made" >&2; trap - ERR; cmd_down' ERR
  echo "$n" >"$state/n"
  ip link add "$bridge" type bridge stp_state 0 forward_delay 0
  ip link set "$bridge" type bridge nf_call_iptables 0 nf_call_ip6tables 0 nf_call_arptables 0 \
    2>/dev/null || true
  ip addr add "$subnet.254/24" dev "$bridge"
  ip link set "$bridge" up
  local k nsk
  for k in $(seq 0 "$n"); do
    nsk=$(ns "$k")
    ip netns add "$nsk"
    ip link add "$prefix-h$k" type veth peer name "$prefix-n$k"
    ip link set "$prefix-n$k" netns "$nsk"
    ip -n "$nsk" link set "$prefix-n$k" name eth0
    ip link set "$prefix-h$k" master "$bridge" up
    ip netns exec "$nsk" sysctl -qw net.ipv6.conf.all.disable_ipv6=1 >/dev/null 2>&1 || true
    ip -n "$nsk" addr add "$(addr "$k")/24" dev eth0
    ip -n "$nsk" link set lo up
    ip -n "$nsk" link set eth0 up
  done
  apply_shape
  trap - ERR
}

cmd_shape() {
  [ -f "$state/n" ] || die "$prefix is not up"
  parse_shape "$@"
  apply_shape
}

cmd_down() {
  local k nsk pids
  if [ -d "$state" ]; then stop_daemons; fi
  for nsk in $(ip netns list 2>/dev/null | awk '{print $1}' | grep -E "^$prefix-ns[0-9]+$" || true); do
    # whatever the benchmark left running in its own namespaces
    mapfile -t pids < <(ip netns pids "$nsk" 2>/dev/null || true)
    if [ ${#pids[@]} -gt 0 ]; then
      echo "netem: stopping processes left in $nsk: ${pids[*]}" >&2
      kill -TERM "${pids[@]}" 2>/dev/null || true
      sleep 0.2
      mapfile -t pids < <(ip netns pids "$nsk" 2>/dev/null || true)
      if [ ${#pids[@]} -gt 0 ]; then kill -KILL "${pids[@]}" 2>/dev/null || true; fi
    fi
    ip netns del "$nsk" 2>/dev/null || true
  done
  for k in $(ip -o link show 2>/dev/null | awk -F': ' '{print $2}' | sed 's/@.*//' |
    grep -E "^$prefix-h[0-9]+$" || true); do
    ip link del "$k" 2>/dev/null || true
  done
  ip link del "$bridge" 2>/dev/null || true
  rm -rf "$state"
  return 0
}

cmd_status() {
  [ -f "$state/config" ] || { echo "netem: $prefix is not up"; return 0; }
  cat "$state/config"
  local k n
  n=$(cat "$state/n")
  for k in $(seq 0 "$n"); do
    echo "$(ns "$k") $(addr "$k"):"
    tc -n "$(ns "$k")" qdisc show dev eth0 | sed 's/^/  eth0: /'
    tc qdisc show dev "$prefix-h$k" | sed "s/^/  $prefix-h$k: /"
    [ -f "$state/delayd-$k.ready" ] && echo "  delayd: $(cat "$state/delayd-$k.ready")"
  done
}

cmd_hosts() {
  [ -f "$state/n" ] || die "$prefix is not up"
  local k
  for k in $(seq 0 "$(cat "$state/n")"); do addr "$k"; done
}

cmd_exec() {
  [ $# -ge 2 ] || die "usage: netem.sh exec K CMD..."
  local k=$1
  shift
  exec ip netns exec "$(ns "$k")" "$@"
}

case ${1:-} in
  check) cmd_check ;;
  up) shift; cmd_up "$@" ;;
  shape) shift; cmd_shape "$@" ;;
  down) cmd_down ;;
  status) cmd_status ;;
  hosts) cmd_hosts ;;
  exec) shift; cmd_exec "$@" ;;
  *) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 2 ;;
esac
