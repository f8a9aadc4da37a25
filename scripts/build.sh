#!/usr/bin/env bash
# Configures and builds dmmr into build/ (binaries in build/bin/).
# Arguments name targets to build (default: everything, tests included).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${DMMR_BUILD_DIR:-build}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=${DMMR_BUILD_TYPE:-RelWithDebInfo} >/dev/null
targets=()
for t in "$@"; do targets+=(--target "$t"); done
cmake --build "$build" -j "$(nproc)" "${targets[@]}"
