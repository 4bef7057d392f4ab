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
{ set +x; } 2>/dev/null
echo "demo: outputs in $OUT/ (open $OUT/liver.vtu and $OUT/beam/frames.pvd in ParaView)"
