#!/usr/bin/env bash
# The README's first command: set up, build (Release), and run the main job on bundled
# samples: prepare a tet mesh from the segmented liver, report its quality, convert it, and
# simulate the sample beam scene. Outputs go to ${DEMO_OUT:-demo-out}.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
BUILD_DIR=${BUILD_DIR:-build}
OUT=${DEMO_OUT:-demo-out}
mkdir -p "$OUT"
INCISE="$BUILD_DIR/cli/incise"
set -x
"$INCISE" prepare samples/liver.inr.gz -o "$OUT/liver.vtu"
"$INCISE" info "$OUT/liver.vtu"
"$INCISE" convert "$OUT/liver.vtu" "$OUT/liver.msh"
"$INCISE" simulate samples/scenes/beam.json -o "$OUT/beam"
"$INCISE" cut "$OUT/liver.vtu" -o "$OUT/liver_cut.msh" --blade 140 60 205 140 160 205 --sweep 0 0 -90 --steps 10 --json "$OUT/liver_cut.json"
"$INCISE" simulate samples/scenes/liver_cut.json -o "$OUT/liver_cut"
{ set +x; } 2>/dev/null
echo "demo: outputs in $OUT/ (open $OUT/liver.vtu, $OUT/beam/frames.pvd and $OUT/liver_cut/frames.pvd in ParaView; colour by cut_faces)"
