#!/bin/sh
# Bundled layouts and material libraries by name, in every command that takes
# --layout, --chart or --materials (and a scene's "library"): a bare name works from
# any directory, a file of that name in the working directory wins over it, and an
# unknown name fails (exit 1) with the bundled names listed.
# usage: test_bundled_names.sh KOGEI HAVE_APRILTAG HAVE_RENDER
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
case $KOGEI in /*) ;; *) KOGEI=$(pwd)/$KOGEI ;; esac
HAVE_APRILTAG=${2:-1}
HAVE_RENDER=${3:-1}
DEMO=${KOGEI_SOURCE_ROOT:?}/fixtures/demo
TCS=/usr/share/colord/ref/CIE-TCS.sp
kg_temp
cd "$T" || exit 1
CAM=$DEMO/site_camera.csv

# --materials default
expect_exit 0 "$KOGEI" model --material gold --materials default -o gold.csv
expect_exit 0 "$KOGEI" sim image --materials default --only gold,silver,urushi --camera "$CAM" \
	--illuminant A --patch-size 8 -o img.tif
expect_exit 1 "$KOGEI" model --material gold --materials no-such-library -o x.csv
check "an unknown library lists the bundled ones" grep -q "no-such-library.*default" err
expect_exit 1 "$KOGEI" sim image --materials no-such-library --camera "$CAM" --illuminant A \
	-o x.tif
check "sim image: an unknown library lists the bundled ones" grep -q "default" err
# A file named like a bundled library wins: this one has gold only.
cat >default <<'EOF'
{"format": "kogei-materials/1", "materials": [
  {"name": "gold", "kind": "metal", "nk": {"model": "rakic1998-ld", "element": "Au"}}]}
EOF
expect_exit 1 "$KOGEI" model --material silver --materials default -o x.csv
check "a file named default wins over the bundled library" grep -q "the library has: gold)" err
rm default

if [ -r "$TCS" ]; then
	expect_exit 0 "$KOGEI" sim patches --spectra "$TCS" --camera "$DEMO/reference_camera.csv" \
		--illuminant D65 -o ref.cgats
	expect_exit 0 "$KOGEI" sim patches --spectra "$TCS" --camera "$CAM" --illuminant A \
		-o site.cgats
	expect_exit 0 "$KOGEI" calib reference --spectra "$TCS" --rgb ref.cgats -o ref.json
	expect_exit 0 "$KOGEI" calib camera --reference ref.json --rgb site.cgats -o cam.json
	expect_exit 0 "$KOGEI" classify --calib cam.json --materials default --only gold,silver,urushi \
		img.tif -o labels.hdr
	check "classify by library name wrote labels" test -s labels.json
	expect_exit 1 "$KOGEI" classify --calib cam.json --materials no-such-library img.tif \
		-o labels2.hdr
	check "classify: an unknown library lists the bundled ones" grep -q "default" err

	# measure --chart with a bundled layout: the sim spectrometer reads the TCS spectra
	expect_exit 0 "$KOGEI" measure --spectro "sim:$TCS" --chart cie-tcs-frame --yes -o m.cgats
	check "measure --chart cie-tcs-frame measured 15 patches" grep -q "^NUMBER_OF_SETS 15" m.cgats
fi
expect_exit 1 "$KOGEI" measure --spectro "sim:$TCS" --chart no-such-layout --yes -o m2.cgats
check "measure: an unknown layout lists the bundled ones" \
	grep -q "no-such-layout.*colorchecker24-frame.*cie-tcs-frame" err

# --layout NAME (the unknown name is refused before the tags are needed)
expect_exit 1 "$KOGEI" sim chart --layout no-such-layout --camera "$CAM" --illuminant D65 -o x.tif
check "sim chart: an unknown layout lists the bundled ones" grep -q "colorchecker-sg-frame" err
if [ "$HAVE_APRILTAG" = 1 ]; then
	expect_exit 0 "$KOGEI" sim chart --layout colorchecker24-frame --camera "$CAM" --illuminant D65 \
		--width 640 --height 480 -o cc24.tif
	expect_exit 0 "$KOGEI" sim chart --layout cie-tcs-frame --camera "$CAM" --illuminant D65 \
		--width 640 --height 480 -o tcs.tif
	for l in colorchecker24-frame colorchecker-passport-frame colorchecker-sg-frame cie-tcs-frame; do
		expect_exit 0 "$KOGEI" chart print --layout $l -o $l.svg
	done
	expect_exit 0 "$KOGEI" chart detect --layout colorchecker24-frame cc24.tif -o cc24.cgats
	check "chart detect by name: 24 patches" grep -q "^NUMBER_OF_SETS 24" cc24.cgats
	expect_exit 0 "$KOGEI" chart detect --layout cie-tcs-frame tcs.tif -o tcs.cgats
	expect_exit 1 "$KOGEI" chart detect --layout no-such-layout tcs.tif -o x.cgats
	check "chart detect: an unknown layout lists the bundled ones" grep -q "colorchecker-passport-frame" err
	expect_exit 0 "$KOGEI" acquire --camera "sim:$T/tcs.tif?format=rgb16&fullwell=100000" \
		--out S --kind chart --frames 1 --exposure auto --target 0.7 --layout cie-tcs-frame
	expect_exit 1 "$KOGEI" acquire --camera "sim:$T/tcs.tif?format=rgb16&fullwell=100000" \
		--out S --kind chart --frames 1 --exposure auto --target 0.7 --layout no-such-layout
	check "acquire: an unknown layout lists the bundled ones" grep -q "cie-tcs-frame" err
fi

# a scene's "library" by name
if [ "$HAVE_RENDER" = 1 ]; then
	cat >scene.json <<'EOF'
{"format": "kogei-scene/1",
 "mesh": {"generator": "icosphere", "level": 2},
 "materials": {"library": "default", "material": "shakudo"},
 "light": {"illuminant": "D65", "direction": [1, -1, 1.5]},
 "camera": {"position": [0, -4, 0.5], "look_at": [0, 0, 0], "up": [0, 0, 1],
            "fov_deg": 35, "width": 32, "height": 24},
 "sampling": {"spp": 1, "wavelengths": 4, "bounces": 1, "seed": 1}}
EOF
	expect_exit 0 "$KOGEI" render --scene scene.json -o scene.png --quiet
	sed 's/"library": "default"/"library": "no-such-library"/' scene.json >bad.json
	expect_exit 1 "$KOGEI" render --scene bad.json -o bad.png --quiet
	check "render: an unknown library lists the bundled ones" grep -q "no-such-library.*default" err
fi

[ $fail = 0 ] && echo "bundled-names: ok"
exit $fail
