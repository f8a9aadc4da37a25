#!/usr/bin/env bash
# Occlusion culling on one client: triangles drawn against the frustum and the
# exactly visible set, frame time against dmmr-reference, pipelined against
# serialised stages (both with the defaults), and the speed-against-error
# sweep of the faster settings (hardware queries, where thresholds apply).
# usage: scripts/bench/visibility.sh   (writes out/bench/vis/, prints Markdown)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=build/bin
out=out/bench/vis
size=${DMMR_BENCH_SIZE:-512}
mkdir -p "$out"

# shellcheck source=lib.sh
source scripts/bench/lib.sh
scene plant10m plant --seed 1 --triangles 10000000 --frames 60
scene monument4m monument --seed 1 --triangles 4000000 --frames 60
for s in plant10m monument4m; do  # the same scenes with occluder levels of detail
  [ -d "out/bench/$s-lod.scene" ] || $bin/dmmr-preprocess "out/bench/$s.osgb" -o "out/bench/$s-lod.scene" \
    --lod-ratio 0.25 --no-progress >/dev/null
done

render() {  # scene, path, label, extra options... (the scene dir may be overridden by SCENE_DIR)
  local s=$1 p=$2 label=$3
  shift 3
  "${mpi[@]}" $bin/dmmr-render --scene "${SCENE_DIR:-out/bench/$s.scene}" --walkthrough "$p" --out "$out/$label" \
    --width "$size" --height "$size" --stats "$out/$label.csv" --no-progress "$@"
  $bin/dmmr-compare "$out/ref-$s" "$out/$label" --csv "$out/$label.cmp.csv" --min-psnr 0 \
    --max-diff-pixels 999999999 >/dev/null
}

for s in plant10m monument4m; do
  p=walkthroughs/$s.path
  $bin/dmmr-reference --scene "out/bench/$s.scene" --walkthrough "$p" --out "$out/ref-$s" \
    --width "$size" --height "$size" --stats "$out/ref-$s.csv" --exact-visible --no-progress
  render "$s" "$p" "$s-pipelined"
  render "$s" "$p" "$s-serial" --in-flight 1
  render "$s" "$p" "$s-frustum-only" --visibility off
  for t in 0 16 64; do
    for k in 0 3 10; do
      render "$s" "$p" "$s-t$t-k$k" --visibility queries --stages split --query-threshold $t --keep-frames $k
    done
  done
  SCENE_DIR=out/bench/$s-lod.scene render "$s" "$p" "$s-lod" --visibility queries --stages split --occluder-lod --keep-frames 0
  SCENE_DIR=out/bench/$s-lod.scene render "$s" "$p" "$s-lod-t16" --visibility queries --stages split --occluder-lod --query-threshold 16 --keep-frames 0
done
python3 scripts/bench/visibility_report.py "$out" plant10m monument4m
