#!/bin/sh
# docs/blender-render.png and the per-material table of docs/render.md from real runs:
# the demo object's glb (kogei export of tests/render/blender_scene.json) rendered by
# Blender with Cycles on the CPU (tests/render/blender_render.py) at 640 x 480, 128
# samples, the sky behind it; then the comparison test (tests/render/test_blender.sh),
# whose table is printed. Needs blender (scripts/setup.sh) and a build with Embree.
# usage: scripts/docs_blender.sh [BUILD_DIR]
set -eu
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${1:-$ROOT/build}
KOGEI=$BUILD/cli/kogei
command -v blender >/dev/null || { echo "docs_blender.sh: blender not found" >&2; exit 1; }
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
scene=$ROOT/tests/render/blender_scene.json
"$KOGEI" export --scene "$scene" -o "$T/object.glb"
blender -b --factory-startup --python-exit-code 1 \
	--python "$ROOT/tests/render/blender_render.py" -- --glb "$T/object.glb" \
	--scene "$scene" --raw "$T/shot.f32" --png "$T/shot.png" --samples 128 --seed 1 \
	--threads 2 --width 640 --height 480 --opaque 1 >"$T/log" 2>&1 ||
	{ tail -n 30 "$T/log"; exit 1; }
mv "$T/shot.png" "$ROOT/docs/blender-render.png"
echo "docs_blender.sh: wrote docs/blender-render.png"
"$ROOT/tests/render/test_blender.sh" "$KOGEI" "$ROOT" 1 "$T/test"
