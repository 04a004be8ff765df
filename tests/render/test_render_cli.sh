#!/bin/sh
# `kogei render` end to end: 1 and 2 threads give byte-identical PNG and TIFF (and a
# different seed does not), scene errors exit 1 naming the scene file and the field
# and leave no output, usage errors exit 2.
# usage: test_render_cli.sh KOGEI SOURCE_ROOT HAVE_EMBREE
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
SRC=$2
kg_need "${3:-0}" "the renderer was built without Embree 3 (libembree-dev)"
kg_temp

expect_exit 0 "$KOGEI" render --help
grep -q "kogei render --scene" "$T/out" || { echo "FAIL: render --help"; fail=1; }

# Determinism: the tsuba scene (per-face materials, ground plane, light and
# environment), small, at 1 and 2 threads.
scene=$SRC/fixtures/scenes/tsuba.json
small="--width 64 --height 48 --spp 4 --quiet"
expect_exit 0 "$KOGEI" render --scene "$scene" $small --threads 1 -o "$T/t1.png" --linear "$T/t1.tif"
expect_exit 0 "$KOGEI" render --scene "$scene" $small --threads 2 -o "$T/t2.png" --linear "$T/t2.tif"
cmp -s "$T/t1.png" "$T/t2.png" || { echo "FAIL: PNG differs between 1 and 2 threads"; fail=1; }
cmp -s "$T/t1.tif" "$T/t2.tif" || { echo "FAIL: TIFF differs between 1 and 2 threads"; fail=1; }
expect_exit 0 "$KOGEI" render --scene "$scene" $small --threads 2 --seed 99 -o "$T/t3.png"
cmp -s "$T/t1.png" "$T/t3.png" && { echo "FAIL: another seed gives the same image"; fail=1; }
[ -s "$T/t1.tif" ] || { echo "FAIL: no TIFF written"; fail=1; }

# Usage errors.
expect_exit 2 "$KOGEI" render -o "$T/x.png"
expect_exit 2 "$KOGEI" render --scene "$scene"
expect_exit 2 "$KOGEI" render --scene "$scene" -o "$T/x.png" --spp 0
expect_exit 2 "$KOGEI" render --scene "$scene" -o "$T/x.png" --wavelengths 62
expect_exit 2 "$KOGEI" render --scene "$scene" -o "$T/x.png" --bogus
# A missing output folder is found before rendering.
expect_exit 1 "$KOGEI" render --scene "$scene" -o "$T/no/such/dir/x.png"
grep -q "no/such/dir" "$T/err" || { echo "FAIL: missing folder not named"; fail=1; }
# An unknown material for --material names the library's.
expect_exit 1 "$KOGEI" render --scene "$scene" $small -o "$T/x.png" --material unobtainium
grep -q "unobtainium" "$T/err" && grep -q "gold" "$T/err" || { echo "FAIL: --material message"; cat "$T/err"; fail=1; }

# Scene errors: each a variant of a good scene, the expected text in the message.
good='"format": "kogei-scene/1",
 "mesh": {"generator": "icosphere", "level": 2},
 "materials": {"material": "gold"},
 "light": {"illuminant": "D65", "direction": [1, -1, 1]},
 "environment": {"illuminant": "D65", "intensity": 0.5},
 "camera": {"position": [0, -4, 0], "look_at": [0, 0, 0], "fov_deg": 30, "width": 8, "height": 8},
 "sampling": {"spp": 1}'
printf '{%s}\n' "$good" >"$T/good.json"
expect_exit 0 "$KOGEI" render --scene "$T/good.json" -o "$T/good.png" --quiet
n=0
bad() { # sed expression, expected text in the message
	n=$((n + 1))
	printf '{%s}\n' "$good" | sed "$1" >"$T/bad$n.json"
	rm -f "$T/bad.png" "$T/bad.tif"
	expect_exit 1 "$KOGEI" render --scene "$T/bad$n.json" -o "$T/bad.png" --linear "$T/bad.tif" --quiet
	if ! grep -q "bad$n.json" "$T/err" || ! grep -q -- "$2" "$T/err"; then
		echo "FAIL: scene error '$1': expected the file and '$2' in:"; cat "$T/err"; fail=1
	fi
	if ls "$T" | grep -q -e "^bad\.png" -e "^bad\.tif" -e "^\.bad"; then
		echo "FAIL: scene error '$1' left output behind"; ls "$T"; fail=1
	fi
}
bad 's/kogei-scene\/1/kogei-scene\/9/' "key 'format'"
bad 's/"camera"/"camrea"/' "camrea"
bad 's/"fov_deg": 30/"fov_deg": 0/' "camera.fov_deg"
bad 's/"width": 8/"width": -1/' "camera.width"
bad 's/"look_at": \[0, 0, 0\]/"look_at": [0, -4, 0]/' "camera.look_at"
bad 's/"position": \[0, -4, 0\], //' "camera.position"
bad 's/"material": "gold"/"material": "unobtainium"/' "materials.material"
bad 's/"material": "gold"/"material": "gold", "face_ids": {"0": "gold"}/' "exactly one of"
bad 's/"material": "gold"/"face_ids": {"0": "gold"}/' "materials.face_ids"
bad 's/"illuminant": "D65", "direction"/"illuminant": "Z99", "direction"/' "light.illuminant"
bad 's/\[1, -1, 1\]/[0, 0, 0]/' "light.direction"
bad 's/"light": {[^}]*},//; s/"environment": {[^}]*},//' "'light' and 'environment'"
bad 's/"intensity": 0.5/"intensity": 0.5, "image": "missing.tif"/' "environment.image"
bad 's/"spp": 1/"spp": 1, "wavelengths": "some"/' "sampling.wavelengths"
bad 's/"spp": 1/"spp": 1, "bounces": 0/' "sampling.bounces"
bad 's/{"generator": "icosphere", "level": 2}/"missing.ply"/' "key 'mesh'.*missing.ply"
bad 's/"generator": "icosphere"/"ply": "x.ply", "generator": "icosphere"/' "both \"ply\" and \"generator\""
bad 's/"generator": "icosphere"/"generator": "cube"/' "mesh.generator"
bad 's/"level": 2/"level": 11/' "mesh.level"
bad 's/"material": "gold"/"library": "nolib.json", "material": "gold"/' "materials.library"
bad 's/"sampling": {"spp": 1}/"sampling": {"spp": 1,}/' ".json:[0-9]*:[0-9]*:"

exit $fail
