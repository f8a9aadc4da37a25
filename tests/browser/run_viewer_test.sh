#!/usr/bin/env bash
# CTest browser_viewer (labels browser, mpi): the interactive viewer end to end.
# Makes a 20k-triangle plant, starts `mpirun -np 3 dmmr-render --serve
# 127.0.0.1:0` (a server and 2 clients, 256x256), reads the URL it prints, and
# runs viewer_test.js, which opens the page in headless Chromium and checks:
#   - the token: the page and the socket refuse a wrong or missing token
#     (HTTP 403), accept the right one; the page served is
#     server/viewer/index.html byte for byte;
#   - the Hello (size, clients, up, the home pose: --walkthrough's first
#     point) and a first frame for the first pose, the home pose;
#   - an orbit drag sends poses and brings frames, JPEG while moving, whose
#     pixels differ from the first frame's;
#   - the still frame (PNG) that follows is shown exactly on the canvas and is
#     pixel-identical to dmmr-reference's frame for the pose its header
#     reports (written as a one-line AnimationPath);
#   - the Record button's AnimationPath ends at that pose, bit for bit, and
#     its last point renders the same frame in dmmr-reference;
#   - fly mode moves along the view; Home brings back the first frame exactly;
#   - the overlay's triangles, frame kind and one bar per client.
# The screenshot goes to OUT_DIR/viewer.png (docs/images/viewer.png is one).
# Exits 77 (skipped), saying why, when Chromium, node or the npm packages
# (tests/browser/node_modules: `npm ci`, which scripts/install-deps.sh runs)
# are missing. mpirun and everything it started are ended on every exit.
# usage: run_viewer_test.sh BIN_DIR OUT_DIR
set -euo pipefail
bin=${1:?usage: run_viewer_test.sh BIN_DIR OUT_DIR}
out=${2:?usage: run_viewer_test.sh BIN_DIR OUT_DIR}
here=$(cd "$(dirname "$0")" && pwd)
src=$(cd "$here/../.." && pwd)
chromium=${DMMR_CHROMIUM:-/usr/bin/chromium}
clients=2

skip() { echo "SKIP: $*"; exit 77; }
[ -x "$chromium" ] || skip "no $chromium (Debian's chromium package; scripts/install-deps.sh installs it)"
command -v node >/dev/null || skip "no node (Debian's nodejs package; scripts/install-deps.sh installs it)"
node_major=$(node -p 'process.versions.node.split(".")[0]')
[ "$node_major" -ge 18 ] || skip "node $(node --version) is older than playwright-core needs (18)"
[ -f "$here/node_modules/playwright-core/package.json" ] ||
  skip "no tests/browser/node_modules/playwright-core: run (cd tests/browser && npm ci) (scripts/install-deps.sh does)"

for tool in dmmr-scenegen dmmr-preprocess dmmr-render dmmr-reference dmmr-compare; do
  [ -x "$bin/$tool" ] || { echo "FAIL: $bin/$tool is not built"; exit 1; }
done
# (Into a file first: grep -q quitting early would SIGPIPE dmmr-render under pipefail.)
work=$(mktemp -d "${TMPDIR:-/tmp}/dmmr-browser-XXXXXX")
"$bin/dmmr-render" --help >"$work/help.txt" 2>&1 || true
if ! grep -q -a -- '--serve' "$work/help.txt"; then
  rm -rf "$work"
  echo "FAIL: $bin/dmmr-render has no --serve option"
  exit 1
fi
mkdir -p "$out"
pid="" node_pid=""
cleanup() {
  local rc=$?
  # node first: playwright closes its Chromium on SIGTERM.
  if [ -n "$node_pid" ] && kill -0 "$node_pid" 2>/dev/null; then
    kill -TERM "$node_pid" 2>/dev/null || true
    wait "$node_pid" 2>/dev/null || true
  fi
  if [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null; then
    # SIGTERM ends the run in order (docs/interactive.md); mpirun passes it on.
    kill -TERM "$pid" 2>/dev/null || true
    for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    if kill -0 "$pid" 2>/dev/null; then
      echo "browser test: mpirun did not end 10 s after SIGTERM; killing its process group"
      kill -KILL -- "-$pid" 2>/dev/null || true
      pkill -KILL -P "$pid" 2>/dev/null || true
    fi
  fi
  if [ "$rc" -ne 0 ] && [ "$rc" -ne 77 ] && [ -f "$work/server.log" ]; then
    echo "---- dmmr-render's output (last 40 lines)"
    tail -n 40 "$work/server.log"
  fi
  if [ -n "${DMMR_KEEP_TEST_FILES:-}" ]; then echo "kept $work"; else rm -rf "$work"; fi
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 1' INT TERM HUP

echo "== a 20k-triangle plant in $work"
"$bin/dmmr-scenegen" plant --seed 1 --triangles 20000 --geodes 500 -o "$work/plant.osgb" --frames 2
"$bin/dmmr-preprocess" "$work/plant.osgb" -o "$work/scene"

# Its own Open MPI session directory: jobs started at once under one TMPDIR
# can race to create it (open-mpi/ompi#8510), as tests/support explains.
mkdir -p "$work/mpi"
mpi=(env TMPDIR="$work/mpi" mpirun --oversubscribe --bind-to none -np $((clients + 1)))
[ "$(id -u)" -eq 0 ] && mpi+=(--allow-run-as-root)
# Sanitizer builds' settings reach every rank, as in tests/support.
for v in ASAN_OPTIONS LSAN_OPTIONS UBSAN_OPTIONS TSAN_OPTIONS; do
  [ -n "${!v:-}" ] && mpi+=(-x "$v")
done
# Its own session and process group, so that nothing it starts can outlive the test.
echo "== ${mpi[*]} dmmr-render --serve 127.0.0.1:0 (home: the plant's path's first point)"
: >"$work/server.log"
setsid "${mpi[@]}" "$bin/dmmr-render" --scene "$work/scene" --serve 127.0.0.1:0 \
  --walkthrough "$work/plant.path" --width 256 --height 256 --no-progress \
  </dev/null >"$work/server.log" 2>&1 &
pid=$!

url=""
for _ in $(seq 600); do
  url=$(grep -o 'dmmr-render: serving http://[^ ]*' "$work/server.log" | head -n 1 | sed 's/^dmmr-render: serving //' || true)
  [ -n "$url" ] && break
  kill -0 "$pid" 2>/dev/null || { echo "FAIL: dmmr-render ended before it printed its URL"; exit 1; }
  sleep 0.1
done
[ -n "$url" ] || { echo "FAIL: dmmr-render printed no 'serving http://...' line in 60 s"; exit 1; }
echo "== $url"

# In the background and waited for, so that a signal reaches the trap at once
# (bash runs traps only between foreground commands).
node "$here/viewer_test.js" --url "$url" --bin "$bin" \
  --scene "$work/scene" --home "$work/plant.path" --work "$work" --out "$out" --clients "$clients" \
  --page "$src/server/viewer/index.html" &
node_pid=$!
wait "$node_pid"
