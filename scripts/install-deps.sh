#!/usr/bin/env bash
# Installs the Debian packages dmmr needs, only those missing, then the browser
# test's npm packages (tests/browser: playwright-core, driving Debian's
# chromium) when node_modules is missing. Idempotent.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(
  cmake ninja-build g++ pkg-config
  libopenscenegraph-dev openscenegraph
  libosmesa6-dev libegl-dev libgl-dev libegl-mesa0
  libopenmpi-dev openmpi-bin
  zlib1g-dev liblz4-dev libpng-dev
  libturbojpeg0-dev libboost-dev  # interactive mode: JPEG frames, Boost.Beast
  libmeshoptimizer-dev libcli11-dev nlohmann-json3-dev
  libassimp-dev  # glTF, FBX, 3MF, OFF inputs
  libembree-dev  # Embree 3: the clients' ray tracer (client/raytrace.h)
  googletest libgtest-dev
  clang libclang-rt-14-dev
  libasan8 libubsan1 libtsan2  # gcc's sanitizer runtimes (CMakePresets.json)
  python3 time
  python3-matplotlib
  iptables iproute2  # network emulation (scripts/netem: NFQUEUE delay, namespaces, tc)
  chromium  # the viewer page's browser test (tests/browser), headless
)
# node and npm for that test, from Debian unless a node is already installed
# (another distribution's nodejs package, e.g. NodeSource's, brings its own npm
# and conflicts with Debian's npm).
command -v node >/dev/null || packages+=(nodejs npm)

# tests/browser/node_modules from its package-lock.json, when missing or older
# than the lock file. Without the npm registry this only warns: the browser
# test then skips, saying why.
npm_packages() {
  local dir=tests/browser
  [ -f $dir/node_modules/playwright-core/package.json ] &&
    ! [ $dir/package-lock.json -nt $dir/node_modules/.package-lock.json ] && return 0
  command -v npm >/dev/null || { echo "install-deps: no npm; the browser test will be skipped" >&2; return 0; }
  echo "install-deps: npm ci in tests/browser (playwright-core; no browser is downloaded)"
  if ! (cd $dir && PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 npm ci --no-audit --no-fund); then
    rm -rf $dir/node_modules
    echo "install-deps: npm ci failed in $dir; the browser test will be skipped" >&2
  fi
}

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  npm_packages
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
npm_packages
