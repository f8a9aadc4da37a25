#!/usr/bin/env bash
# mpirun with rank k inside namespace k of what scripts/netem/netem.sh up made,
# MPI over TCP only (docs/netem.md):
#   mpirun-netem.sh [MPIRUN_OPTION...] -- PROGRAM [ARG...]
# -np defaults to N+1 (one rank per namespace; rank 0 in PREFIX-ns0); give -np to
# change it (ranks then go round robin over the namespaces). mpirun itself runs
# in the root namespace and reaches its daemons over the bridge (SUBNET.254);
# netem-rsh.sh starts them in the namespaces. DMMR_NETEM_PREFIX and
# DMMR_NETEM_SUBNET select the setup, as for netem.sh. DMMR_NETEM_DRY=1 prints
# the mpirun command instead of running it.
# Ranks yield the CPU while they wait (mpi_yield_when_idle 1, what mpirun does
# by itself when it knows a machine is oversubscribed; here every daemon sees
# one rank on a 2-core "node" and would busy-poll, and a busy-polling rank that
# shares the cores with other work picks up its messages late: docs/netem.md).
# DMMR_NETEM_YIELD=0 leaves it to mpirun.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
prefix=${DMMR_NETEM_PREFIX:-dmmr}
state=/run/$prefix-netem
[ -f "$state/config" ] || { echo "mpirun-netem: $prefix is not up (scripts/netem/netem.sh up N ...)" >&2; exit 1; }
n=$(sed -n 's/^n=//p' "$state/config")
subnet=$(sed -n 's/^subnet=//p' "$state/config")
export DMMR_NETEM_PREFIX=$prefix DMMR_NETEM_SUBNET=$subnet

opts=()
np=""
while [ $# -gt 0 ] && [ "$1" != -- ]; do
  case $1 in -np | -n | --np | -c) np=$2 ;; esac
  opts+=("$1")
  shift
done
[ "${1:-}" = -- ] || { echo "usage: mpirun-netem.sh [MPIRUN_OPTION...] -- PROGRAM [ARG...]" >&2; exit 2; }
shift
[ $# -ge 1 ] || { echo "mpirun-netem.sh: no program" >&2; exit 2; }

hostfile=$state/hostfile
for k in $(seq 0 "$n"); do echo "$subnet.$((k + 1)) slots=1"; done >"$hostfile"
# shellcheck disable=SC2054 # "tcp,self" is one argument
cmd=(mpirun --hostfile "$hostfile" --map-by node --bind-to none --oversubscribe
  --mca plm_rsh_agent "$here/netem-rsh.sh" --mca plm_rsh_no_tree_spawn 1
  --mca pml ob1 --mca btl tcp,self
  --mca btl_tcp_if_include "$subnet.0/24" --mca oob_tcp_if_include "$subnet.0/24")
[ "${DMMR_NETEM_YIELD:-1}" != 0 ] && cmd+=(--mca mpi_yield_when_idle 1)
[ "$(id -u)" -eq 0 ] && cmd+=(--allow-run-as-root)
[ -z "$np" ] && cmd+=(-np $((n + 1)))
cmd+=("${opts[@]}" "$@")
if [ -n "${DMMR_NETEM_DRY:-}" ]; then
  printf '%q ' "${cmd[@]}"
  echo
  exit 0
fi
exec "${cmd[@]}"
