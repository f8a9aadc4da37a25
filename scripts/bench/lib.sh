# Shared by the one-client benchmark scripts (source it after setting `bin`):
# the launcher for a server and one client, and scene generation into
# out/bench/NAME.{osgb,generated.path,scene}, reused when present.
mpi=(mpirun --oversubscribe --bind-to none -np 2)
[ "$(id -u)" -eq 0 ] && mpi+=(--allow-run-as-root)
# The same without the rank count, for scripts that run several client counts.
launch=(mpirun --oversubscribe --bind-to none)
[ "$(id -u)" -eq 0 ] && launch+=(--allow-run-as-root)

scene() {  # name, scenegen arguments...
  local name=$1
  shift
  mkdir -p out/bench
  [ -f "out/bench/$name.osgb" ] || $bin/dmmr-scenegen "$@" -o "out/bench/$name.osgb" \
    --walkthrough "out/bench/$name.generated.path" >/dev/null
  [ -d "out/bench/$name.scene" ] || $bin/dmmr-preprocess "out/bench/$name.osgb" -o "out/bench/$name.scene" --no-progress >/dev/null
}

diff_frames() {  # reference dir, frames dir, CSV: per-frame differences, never failing the run
  $bin/dmmr-compare "$1" "$2" --csv "$3" --min-psnr 0 --max-diff-pixels 999999999 >/dev/null
}
