#!/usr/bin/env bash
# Compact geometry (issue 5): for the real models in ../shared/models and
# generated 1M-triangle plant and monument scenes, each geometry encoding's
# bytes per triangle against the indexed-face-set baseline, decode throughput,
# and the image error of a walkthrough against the float32 scene's frames.
# usage: scripts/bench/encoding.sh [RUNS]   (decode passes per scene, default 7)
# Writes out/bench/encoding/ (scenes are kept and reused); prints Markdown.
# Needs build/bin/{dmmr-scenegen,dmmr-preprocess,dmmr-reference,dmmr-compare,codec_bench}.
set -euo pipefail
cd "$(dirname "$0")/../.."
runs=${1:-7}
bin=${DMMR_BIN:-build/bin}
out=out/bench/encoding
models=$(realpath -m ../shared/models)
mkdir -p "$out"
export OSG_FILE_PATH="$models"  # the OSG models find their textures as Images/NAME
encodings="float32 meshopt quantized quantized-meshopt"

# name=model pairs; each gets a 20-frame walkthrough: an orbit for a real
# model (scenegen replicate, one copy), the fly-through for generated scenes.
inputs=()
for m in skull/skull.obj koala/koala.obj scorpion/scorpion.obj osg-data-cow.osgt \
  osg-data-dumptruck.osgt osg-data-cessna.osgt osg-data-lz.osgt; do
  if [ ! -f "$models/$m" ]; then
    echo "encoding.sh: $models/$m is absent; skipped" >&2
    continue
  fi
  name=$(basename "${m%%.*}")
  [ -f "$out/$name.path" ] || $bin/dmmr-scenegen replicate --input "$models/$m" --copies 1 \
    --frames 20 -o "$out/$name.osgb" >/dev/null
  inputs+=("$name=$models/$m")
done
for kind in plant monument; do
  [ -f "$out/${kind}1m.osgb" ] || $bin/dmmr-scenegen $kind --seed 1 --triangles 1000000 \
    --frames 20 -o "$out/${kind}1m.osgb" >/dev/null
  inputs+=("${kind}1m=$out/${kind}1m.osgb")
done

names=()
for entry in "${inputs[@]}"; do
  name=${entry%%=*} model=${entry#*=}
  names+=("$name")
  for e in $encodings; do
    scene=$out/$name.$e
    [ -d "$scene" ] || $bin/dmmr-preprocess "$model" -o "$scene" --encoding "$e" --no-progress >/dev/null
    if [ ! -f "$scene.frames/done" ]; then
      rm -rf "$scene.frames"
      $bin/dmmr-reference --scene "$scene" --walkthrough "$out/$name.path" --out "$scene.frames" \
        --width 512 --height 512 --no-progress
      touch "$scene.frames/done"
    fi
    $bin/codec_bench "$scene" "$runs" >"$scene.decode"
    # Exit status 1 means frames differ, which the table reports.
    $bin/dmmr-compare "$out/$name.float32.frames" "$scene.frames" --csv "$scene.compare.csv" \
      >/dev/null || [ $? -eq 1 ]
  done
done
python3 scripts/bench/encoding_report.py "$out" "$encodings" "${names[@]}"
