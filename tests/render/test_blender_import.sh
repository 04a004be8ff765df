#!/bin/sh
# object.glb as File > Import gives it: `kogei export` writes the glb of
# tests/render/blender_scene.json (the demo object, all ten library materials, a D65
# sun and a uniform D65 sky), kogei renders the scene (XYZ and the truth labels), and
# Blender imports the glb and renders it with the file's own camera, light (glTF lux,
# converted by the importer's standard lighting mode) and environment backdrop —
# tests/render/blender_import.py sets nothing from kogei's scene but the image size.
# Per material region the mean colours must be within CIEDE2000 5 on the absolute
# scale (tests/render/blender_compare.py: no normalisation, so a light in the wrong
# units fails it), the same limit as render-blender, whose Blender lights are set
# from the scene instead.
# usage: test_blender_import.sh KOGEI SOURCE_ROOT HAVE_EMBREE [OUT_DIR]
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
read -r W H <<EOT
$("$PY" -c 'import json, sys; c = json.load(open(sys.argv[1]))["camera"]; print(c["width"], c["height"])' "$scene")
EOT

"$KOGEI" export --scene "$scene" -o "$T/object.glb" >"$T/log" 2>&1 ||
	{ echo "FAIL: kogei export"; cat "$T/log"; exit 1; }
if command -v node >/dev/null 2>&1 && [ -d "$SRC/.tools/gltf-validator" ]; then
	node "$SRC/tests/gltf_validate.mjs" "$SRC/.tools/gltf-validator" "$T/object.glb"
	rc=$?
	[ "$rc" = 0 ] || [ "$rc" = 77 ] || { echo "FAIL: glTF-Validator (exit $rc)"; exit 1; }
fi
"$KOGEI" render --scene "$scene" --spp $SPP --wavelengths all --threads 2 --seed 1 --quiet \
	-o "$T/kogei.png" --linear "$T/kogei_xyz.tif" --truth-labels "$T/kogei_labels.hdr" \
	>"$T/log" 2>&1 || { echo "FAIL: kogei render"; cat "$T/log"; exit 1; }
"$BLENDER" -b --factory-startup --python-exit-code 1 \
	--python "$SRC/tests/render/blender_import.py" -- --glb "$T/object.glb" \
	--raw "$T/blender.f32" --png "$T/blender.png" --width "$W" --height "$H" \
	--samples $SPP --seed 1 --threads 2 >"$T/blender.log" 2>&1 ||
	{ echo "FAIL: blender"; tail -n 30 "$T/blender.log"; exit 1; }
grep "blender_import.py:" "$T/blender.log"
echo "kogei render --spp $SPP --wavelengths all; Blender $("$BLENDER" --version 2>/dev/null | head -n 1 | sed 's/Blender //') File > Import, Cycles CPU, $SPP samples"
"$PY" "$SRC/tests/render/blender_compare.py" "$T/kogei_xyz.tif" "$T/kogei_labels.hdr" \
	"$T/blender.f32" --max-de 5 --table "$T/table.md"
