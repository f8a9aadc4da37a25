#!/usr/bin/env bash
# Quick start 3: the interactive viewer on the demo scene. Installs what is
# missing, builds, makes the demo's plant when scripts/demo.sh has not
# (out/demo/scene), and starts a server and 2 clients with `dmmr-render
# --serve`; prints the URL to open in a browser (with the run's token).
# Ctrl-C ends it. docs/interactive.md has the controls and the protocol.
#
# Environment: DMMR_VIEWER_PORT (default 8080; 0: any free port),
# DMMR_VIEWER_ADDR (default 127.0.0.1: this machine only), DMMR_VIEWER_CLIENTS
# (default 2), DMMR_DEMO_OUT, DMMR_DEMO_TRIANGLES, DMMR_DEMO_SIZE as for demo.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh dmmr-scenegen dmmr-preprocess dmmr-render

out=${DMMR_DEMO_OUT:-out/demo}
tris=${DMMR_DEMO_TRIANGLES:-1000000}
size=${DMMR_DEMO_SIZE:-1024}
port=${DMMR_VIEWER_PORT:-8080}
addr=${DMMR_VIEWER_ADDR:-127.0.0.1}
clients=${DMMR_VIEWER_CLIENTS:-2}
bin=build/bin
mpi=(mpirun --oversubscribe --bind-to none -np $((clients + 1)))
[ "$(id -u)" -eq 0 ] && mpi+=(--allow-run-as-root)

if [ ! -f "$out/scene/manifest.json" ]; then
  mkdir -p "$out"
  echo "== generating and preprocessing the demo plant ($tris triangles)"
  $bin/dmmr-scenegen plant --seed 1 --triangles "$tris" -o "$out/plant.osgb" \
    --walkthrough "$out/generated.path" --frames 60 >/dev/null
  $bin/dmmr-preprocess "$out/plant.osgb" -o "$out/scene" --no-progress
fi
echo "== serving (server + $clients clients); open the URL below, Ctrl-C to stop"
# The demo's walkthrough gives the home pose.
exec "${mpi[@]}" $bin/dmmr-render --scene "$out/scene" --walkthrough walkthroughs/demo-plant.path \
  --serve "$addr:$port" --width "$size" --height "$((size * 3 / 4))"
