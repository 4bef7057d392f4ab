#!/usr/bin/env bash
# The viewer's figures on the 27k-tet organ (README, docs/view.md): meshes the bundled
# segmented liver image at 1.7% of its size (`incise tetra`), keeps its largest part (a speck
# would be a free part to the static scene), and runs the browser test with the sample
# liver_cut scene on it. Prints frames/s to the page, KiB per frame, server frame and
# blade-step times. Needs a Release build with the viewer (bash scripts/build.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
W=$(realpath -m "${WORK_DIR:-$BUILD_DIR/view-organ}")
mkdir -p "$W"
if [ ! -f "$W/organ.msh" ]; then
  "$BUILD_DIR/cli/incise" tetra samples/liver.inr.gz -o "$W/organ-raw.msh" --size 1.7%
  /usr/bin/python3 tests/view/largest_part.py "$W/organ-raw.msh" "$W/organ.msh"
fi
sed "s|\"mesh\": \"../liver.msh\"|\"mesh\": \"$W/organ.msh\"|" samples/scenes/liver_cut.json >"$W/organ_cut.json"
/usr/bin/python3 tests/view/browser_test.py "$(realpath "$BUILD_DIR/cli/incise")" "$W/organ_cut.json" "$W/shots" --budget-ms 40
