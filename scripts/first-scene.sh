#!/usr/bin/env bash
# The README's "A first scene", end to end: prepares the liver at 2%, writes the scene, simulates
# it, and takes the README's picture of its last frame in `incise view RUN` (headless Chromium,
# coloured by von Mises stress) into docs/images/first-scene.png. Needs a Release build
# (bash scripts/build.sh). OUT_DIR (default build/first-scene) keeps the mesh, scene and run.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
OUT=$(realpath -m "${OUT_DIR:-$BUILD_DIR/first-scene}")
INCISE=$(realpath "$BUILD_DIR/cli/incise")
mkdir -p "$OUT"
"$INCISE" prepare samples/liver.inr.gz -o "$OUT/liver.vtu" --size 2% -q
# The scene as the README gives it.
sed -n '/^cat > first\/scene.json/,/^EOF$/p' README.md | sed '1d;$d' >"$OUT/scene.json"
rm -rf "$OUT/run"
"$INCISE" simulate "$OUT/scene.json" -o "$OUT/run" -q
/usr/bin/python3 scripts/first_scene_picture.py "$INCISE" "$OUT/run" docs/images/first-scene.png
