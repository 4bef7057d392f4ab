#!/usr/bin/env bash
# The README's `incise trade` figures, regenerated: runs trade on the beam (2 frames) and on the
# liver cut scene, as the README says, and prints each run's figures as the README gives them
# (the reference, the error per level, model and formulation at the scene's solver, springs at
# rest, the recommendations, how long the run took). Needs a Release build (bash scripts/build.sh).
# OUT_DIR (default build/trade-figures) keeps trade.csv, trade.svg and the JSON of each run.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
OUT=$(realpath -m "${OUT_DIR:-$BUILD_DIR/trade-figures}")
mkdir -p "$OUT"
run() {  # NAME SCENE [trade options...]
  local name=$1 scene=$2
  shift 2
  local t0 t1
  t0=$(date +%s%N)
  "$BUILD_DIR/cli/incise" trade "$scene" -o "$OUT/$name" --json "$OUT/$name.json" -q "$@" >"$OUT/$name.out"
  t1=$(date +%s%N)
  /usr/bin/python3 scripts/trade_figures.py "$OUT/$name.json" "incise trade $scene -o out/$name${*:+ $*}" \
    "$(((t1 - t0) / 1000000000))"
}
run trade samples/scenes/beam.json --frames 2
run liver_trade samples/scenes/liver_cut.json
