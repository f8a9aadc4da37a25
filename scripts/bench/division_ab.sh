#!/usr/bin/env bash
# Division settings side by side (issue 16): dmmr-render with each of
# several option sets on the scaling suite's medium scenes (plants4, plants8,
# monuments16 at 1024x768, 40 frames; DMMR_BENCH_SCENES may also name
# skullmesh4, issue 15's four 2.5M-triangle skull meshes in clusters, at
# 512x512 along walkthroughs/skullmesh4.path, 48 frames a turn, and
# skullmesh4-192, the same orbit in 192 frames: walkthroughs/skullmesh4-192.path,
# of which every fourth point is skullmesh4.path's; skullmesh4-whole, the same
# meshes preprocessed unsplit, --cluster-triangles 0), with 1 client (the base of
# efficiency, default options) and with each count in DMMR_BENCH_CLIENTS
# (default "4 16").
# DMMR_BENCH_WH=WxH renders every scene at that size instead (use its own
# DMMR_BENCH_OUT: the references are kept there by scene name).
# DMMR_BENCH_CONFIGS lists the option sets as "label:options;label:options"
# (default: the weights visible and fitted, each without and with the cost
# grid); options beginning with @DIR run DIR/dmmr-render (another build's bin
# directory) with the rest, an A/B of two builds. Every run with
# LP_NUM_THREADS=0, so that a client's stage threads' CPU time is its whole
# cost, free of waiting for one of this machine's cores (the scaling suite's
# method). DMMR_BENCH_REPS rounds (default 2), the
# configurations alternating in each; every frame is compared with
# dmmr-reference's.
# usage: scripts/bench/division_ab.sh   (writes out/bench/division-ab/, prints Markdown)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/division-ab}
reps=${DMMR_BENCH_REPS:-2}
counts=${DMMR_BENCH_CLIENTS:-4 16}
scenes=${DMMR_BENCH_SCENES:-plants4 plants8 monuments16}
default_configs="visible:--weights visible --cost-grid off;visible+grid:--weights visible --cost-grid on;\
fitted:--weights fitted --cost-grid off;fitted+grid:--weights fitted --cost-grid on"
IFS=';' read -r -a sets <<<"${DMMR_BENCH_CONFIGS:-$default_configs}"
models=${DMMR_MODELS:-../shared/models}
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
# Sets sc, path, w and h for scene $1, making it when missing.
scene_of() {
  case $1 in
    skullmesh4 | skullmesh4-192)
      [ -f out/bench/skullmesh4.osgb ] || $bin/dmmr-scenegen replicate \
        --input "$models/skull/skull.obj" --subdivide 5 --copies 4 --path around --frames 48 \
        -o out/bench/skullmesh4.osgb --walkthrough out/bench/skullmesh4.generated.path >/dev/null
      [ -d out/bench/skullmesh4.scene ] || $bin/dmmr-preprocess out/bench/skullmesh4.osgb \
        -o out/bench/skullmesh4.scene --no-progress >/dev/null
      sc=out/bench/skullmesh4.scene path=walkthroughs/skullmesh4.path w=512 h=512
      if [ "$1" = skullmesh4-192 ]; then path=walkthroughs/skullmesh4-192.path; fi
      ;;
    skullmesh4-whole) # the same meshes unsplit: issue 15's "without clustering"
      scene_of skullmesh4
      [ -d out/bench/skullmesh4-whole.scene ] || $bin/dmmr-preprocess out/bench/skullmesh4.osgb \
        -o out/bench/skullmesh4-whole.scene --cluster-triangles 0 --no-progress >/dev/null
      sc=out/bench/skullmesh4-whole.scene
      ;;
    plants4 | plants8)
      scene "$1" replicate --of plant --copies "${1#plants}" --triangles 400000 --geodes 5000 \
        --seed 1 --frames 40
      sc=out/bench/$1.scene path=out/bench/$1.generated.path w=1024 h=768
      ;;
    monuments16)
      scene monuments16 replicate --of monument --copies 16 --triangles 120000 --geodes 500 \
        --seed 1 --frames 40
      sc=out/bench/$1.scene path=out/bench/$1.generated.path w=1024 h=768
      ;;
    *) echo "division_ab.sh: unknown scene $1" >&2 && exit 1 ;;
  esac
  if [ -n "${DMMR_BENCH_WH:-}" ]; then w=${DMMR_BENCH_WH%x*} h=${DMMR_BENCH_WH#*x}; fi
}

for s in $scenes; do
  scene_of "$s"
  if [ ! -f "$out/$s-ref/frame_000001.png" ]; then
    rm -rf "$out/$s-ref"
    $bin/dmmr-reference --scene "$sc" --walkthrough "$path" --out "$out/$s-ref" --width $w \
      --height $h --no-progress >/dev/null
  fi
done

configs=("1|base|")  # clients|label|options
for n in $counts; do
  for set in "${sets[@]}"; do configs+=("$n|${set%%:*}|${set#*:}"); done
done
for r in $(seq 1 "$reps"); do
  for s in $scenes; do
    scene_of "$s"
    for c in "${configs[@]}"; do
      IFS='|' read -r n label opts <<<"$c"
      run=$out/$s-c$n-$label-r$r
      rm -rf "$run"
      render=$bin/dmmr-render
      if [[ $opts == @* ]]; then
        read -r dir opts <<<"$opts"
        render=${dir#@}/dmmr-render
      fi
      # shellcheck disable=SC2086 # opts is a list of options
      LP_NUM_THREADS=0 "${launch[@]}" -np $((n + 1)) -x LP_NUM_THREADS $render \
        --scene "$sc" --walkthrough "$path" --out "$run" --stats "$run.csv" --width $w \
        --height $h --no-progress $opts >/dev/null 2>"$run.log"
      diff_frames "$out/$s-ref" "$run" "$run.cmp.csv"
    done
  done
done
python3 scripts/bench/division_ab_report.py "$out" "$reps" "$scenes" "${configs[@]}"
