#!/usr/bin/env bash
# mpirun's launch agent under scripts/netem/mpirun-netem.sh (--mca plm_rsh_agent):
# "netem-rsh.sh [OPTION...] HOST CMD..." runs CMD with sh, as ssh would, inside
# HOST's namespace: HOST is SUBNET.(k+1) or PREFIX-nsK (DMMR_NETEM_PREFIX,
# DMMR_NETEM_SUBNET as in netem.sh). The command runs with its own UTS namespace
# and hostname PREFIX-nsK (so each MPI "node" has its own name) and its own
# TMPDIR, so the daemons' session directories do not collide.
set -euo pipefail
prefix=${DMMR_NETEM_PREFIX:-dmmr}
subnet=${DMMR_NETEM_SUBNET:-10.199.77}
while [ $# -gt 0 ] && [[ $1 == -* ]]; do shift; done # ssh options (-x and the like)
[ $# -ge 2 ] || { echo "netem-rsh: usage: netem-rsh.sh HOST CMD..." >&2; exit 2; }
host=$1
shift
case $host in
  "$subnet".*) k=$((${host##*.} - 1)) ;;
  "$prefix"-ns*) k=${host#"$prefix"-ns} ;;
  *) echo "netem-rsh: $host is no host of $prefix ($subnet.0/24)" >&2; exit 255 ;;
esac
ns=$prefix-ns$k
ip netns list | grep -qE "^$ns( |$)" || { echo "netem-rsh: no namespace $ns (netem.sh up first)" >&2; exit 255; }
tmp=/run/$prefix-netem/tmp-$k
mkdir -p "$tmp"
# shellcheck disable=SC2016 # $1 and $2 are the inner sh's
exec ip netns exec "$ns" env TMPDIR="$tmp" unshare --uts sh -c 'hostname "$1" && exec sh -c "$2"' sh "$ns" "$*"
