#!/bin/sh
# The demo object's glTF in Blender: `kogei export` writes the glb of
# tests/render/blender_scene.json (the demo object, all ten library materials, a D65
# sun and sky), kogei renders the scene (XYZ and the truth labels), Blender renders the
# glb with Cycles on the CPU from the same camera under the same light
# (tests/render/blender_render.py), and per material region the mean colours must be
# within CIEDE2000 5 (tests/render/blender_compare.py prints the table).
# usage: test_blender.sh KOGEI SOURCE_ROOT HAVE_EMBREE [OUT_DIR]
# OUT_DIR: keep the renders there (scripts/docs_blender.sh); default a temporary folder.
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
SRC=$2
kg_need "${3:-0}" "the renderer was built without Embree 3 (libembree-dev)"
BLENDER=${BLENDER:-$(command -v blender || true)}
if [ -z "$BLENDER" ]; then
	echo "SKIP: blender not found (Debian package blender; scripts/setup.sh installs it)"
	exit 77
fi
PY=$(command -v python3) || { echo "SKIP: python3 not found"; exit 77; }
if [ -n "${4:-}" ]; then
	T=$4
	mkdir -p "$T"
else
	kg_temp
fi
scene=$SRC/tests/render/blender_scene.json
SPP=64

"$KOGEI" export --scene "$scene" -o "$T/object.glb" >"$T/log" 2>&1 ||
	{ echo "FAIL: kogei export"; cat "$T/log"; exit 1; }
"$KOGEI" render --scene "$scene" --spp $SPP --wavelengths all --threads 2 --seed 1 --quiet \
	-o "$T/kogei.png" --linear "$T/kogei_xyz.tif" --truth-labels "$T/kogei_labels.hdr" \
	>"$T/log" 2>&1 || { echo "FAIL: kogei render"; cat "$T/log"; exit 1; }
"$BLENDER" -b --factory-startup --python-exit-code 1 \
	--python "$SRC/tests/render/blender_render.py" -- --glb "$T/object.glb" \
	--scene "$scene" --raw "$T/blender.f32" --png "$T/blender.png" --samples $SPP \
	--seed 1 --threads 2 >"$T/blender.log" 2>&1 ||
	{ echo "FAIL: blender"; tail -n 30 "$T/blender.log"; exit 1; }
grep "blender_render.py:" "$T/blender.log"
echo "kogei render --spp $SPP --wavelengths all; Blender $("$BLENDER" --version 2>/dev/null | head -n 1 | sed 's/Blender //') Cycles CPU, $SPP samples"
"$PY" "$SRC/tests/render/blender_compare.py" "$T/kogei_xyz.tif" "$T/kogei_labels.hdr" \
	"$T/blender.f32" --max-de 5 --table "$T/table.md"
