#!/usr/bin/env bash
# How repeatable a client's measured cost is (issue 16, section 1): the same
# work rendered DMMR_BENCH_REPS times (default 3), so that what differs
# between runs is measurement, not work. plants4 of the scaling suite's
# medium scale (1024x768, 40 frames), every run LP_NUM_THREADS=0; 1 client,
# and 4 clients with a division that does not depend on timing
# (`--weights frustum --cost-model off`: every run gives every client the same
# objects and draws the same triangles, which the report checks), without and
# with `--stage-turns`. The report gives, per configuration, the median over
# client-frames of max/min of the client's cost over the runs, and the
# median over frames of max/mean over the clients of each client's cost
# divided by its median over the runs: the imbalance that noise alone
# measures when the work is the same.
# usage: scripts/bench/cost_noise.sh   (writes out/bench/cost-noise/, prints Markdown)
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${DMMR_BIN:-build/bin}
out=${DMMR_BENCH_OUT:-out/bench/cost-noise}
reps=${DMMR_BENCH_REPS:-3}
mkdir -p "$out"
# shellcheck source=lib.sh
source scripts/bench/lib.sh
scene plants4 replicate --of plant --copies 4 --triangles 400000 --geodes 5000 --seed 1 --frames 40
configs=(  # label|clients|options
  "c1|1|"
  "c4|4|--weights frustum --cost-model off"
  "c4-turns|4|--weights frustum --cost-model off --stage-turns $out/turns.lock"
)
for r in $(seq 1 "$reps"); do
  for c in "${configs[@]}"; do
    IFS='|' read -r label n opts <<<"$c"
    # shellcheck disable=SC2086 # opts is a list of options
    LP_NUM_THREADS=0 "${launch[@]}" -np $((n + 1)) -x LP_NUM_THREADS $bin/dmmr-render \
      --scene out/bench/plants4.scene --walkthrough out/bench/plants4.generated.path \
      --out "$out/frames" --stats "$out/$label-r$r.csv" --width 1024 --height 768 --no-progress \
      $opts >/dev/null 2>&1
  done
done
python3 scripts/bench/cost_noise_report.py "$out" "$reps" "${configs[@]}"
