#!/usr/bin/env bash
# Installs the Debian packages dmmr needs, only those missing. Idempotent.
set -euo pipefail

packages=(
  cmake ninja-build g++ pkg-config
  libopenscenegraph-dev openscenegraph
  libosmesa6-dev libegl-dev libgl-dev libegl-mesa0
  libopenmpi-dev openmpi-bin
  zlib1g-dev liblz4-dev libpng-dev
  libturbojpeg0-dev libboost-dev  # interactive mode: JPEG frames, Boost.Beast
  libmeshoptimizer-dev libcli11-dev nlohmann-json3-dev
  libassimp-dev  # glTF, FBX, 3MF, OFF inputs
  googletest libgtest-dev
  clang libclang-rt-14-dev
  libasan8 libubsan1 libtsan2  # gcc's sanitizer runtimes (CMakePresets.json)
  python3 time
  python3-matplotlib
  iptables iproute2  # network emulation (scripts/netem: NFQUEUE delay, namespaces, tc)
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "install-deps: installing ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
