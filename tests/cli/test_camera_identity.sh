#!/bin/sh
# Camera identity: a chart photographed in a session with the sim camera of serial A
# gives a calibration that records that camera; an object photographed by serial B is
# refused (naming both), by serial A accepted, and --force turns the refusal into a
# warning. Images from outside a session and calibrations without identity proceed
# with a note that nothing was checked.
# usage: test_camera_identity.sh KOGEI SOURCE_ROOT HAVE_APRILTAG
set -u
. "$(dirname "$0")/../lib.sh"
. "$(dirname "$0")/demo_reference.sh"
KOGEI=$1
SRC=$2
kg_temp
demo_reference "${3:-1}"
LIB=$SRC/fixtures/materials/default.json
SENSOR='format=bayer_rggb12&fullwell=20000&read=5'
OBJSENSOR='format=rgb16&bits=12&fullwell=20000&read=5'

# The scenes: the chart and an object (the materials' tiles), linear float.
expect_exit 0 "$KOGEI" sim chart --layout "$LAYOUT" --spectra "$TCS" --camera "$D/site_camera.csv" \
	--illuminant A --tilt 20 --rotate 5 --width 800 --height 600 --white-level 0.8 \
	--noise none --depth float -o "$T/chart.tif"
expect_exit 0 "$KOGEI" sim image --materials "$LIB" --camera "$D/site_camera.csv" --illuminant A \
	--patch-size 20 --gap 4 --columns 5 --background 0 --white-level 0.8 --noise none \
	--depth float -o "$T/object.tif"

acquire() { # session name kind scene uri-keys
	expect_exit 0 "$KOGEI" acquire --out "$1" --name "$2" --kind "$3" --frames 2 \
		--exposure 10000 --gain 0 --dark none --camera "sim:$4?$5"
}
acquire "$T/S" chart chart "$T/chart.tif" "$SENSOR&seed=1&serial=A"
acquire "$T/SB" object object "$T/object.tif" "$OBJSENSOR&seed=2&serial=B"
acquire "$T/SA" object object "$T/object.tif" "$OBJSENSOR&seed=3&serial=A"

# The chart's patch file names the camera.
CHART=$T/S/captures/chart/rgb.tif
[ -e "$CHART" ] || CHART=$T/S/captures/chart/mean.tif # built without OpenCV: the mosaic
expect_exit 0 "$KOGEI" chart detect --layout "$LAYOUT" "$CHART" -o "$T/site.cgats"
check "patch file: CAMERA_BACKEND" grep -q '^CAMERA_BACKEND "sim"' "$T/site.cgats"
check "patch file: CAMERA_MODEL" grep -q '^CAMERA_MODEL "simulated sensor (fullwell 20000 e-, read 5 e-)"' "$T/site.cgats"
check "patch file: CAMERA_SERIAL" grep -q '^CAMERA_SERIAL "A"' "$T/site.cgats"
check "patch file: CAMERA_PIXFMT" grep -q '^CAMERA_PIXFMT "bayer16"' "$T/site.cgats"
check "patch file: CAMERA_WHITE_LEVEL" grep -q '^CAMERA_WHITE_LEVEL "4095"' "$T/site.cgats"
check "patch file: CAMERA_DEMOSAIC" grep -q '^CAMERA_DEMOSAIC "' "$T/site.cgats"
check "patch file: CAPTURE" grep -q '^CAPTURE "chart"' "$T/site.cgats"
expect_exit 0 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/site.cgats" -o "$T/cam.json"
check "calib camera prints the camera" grep -q 'camera: sim camera "simulated sensor (fullwell 20000 e-, read 5 e-)" serial A' "$T/out"
check "camera.json: identity" sh -c "tr -d ' \n' < '$T/cam.json' | grep -q '\"camera\":{\"backend\":\"sim\",\"model\":\"simulatedsensor(fullwell20000e-,read5e-)\",\"serial\":\"A\",\"pixfmt\":\"bayer16\",\"white_level\":4095,'"

# Another camera: refused, naming both, nothing written.
expect_exit 1 "$KOGEI" estimate --calib "$T/cam.json" "$T/SB/captures/object/mean.tif" -o "$T/b.hdr"
check "serial B: names the image's camera" grep -q "serial B" "$T/err"
check "serial B: names the calibration's camera" grep -q "serial A" "$T/err"
check "serial B: names the files" sh -c "grep -q 'SB/captures/object/mean.tif' '$T/err' && grep -q 'cam.json' '$T/err'"
check "serial B: no cube" test ! -e "$T/b.hdr" -a ! -e "$T/b.img"
expect_exit 1 "$KOGEI" classify --calib "$T/cam.json" --materials "$LIB" "$T/SB/captures/object/mean.tif" -o "$T/bl.hdr"
check "classify serial B: refused" grep -q "serial B.*serial A" "$T/err"
check "classify serial B: no labels" test ! -e "$T/bl.hdr"
# --force: a warning, and the cube.
expect_exit 0 "$KOGEI" estimate --calib "$T/cam.json" "$T/SB/captures/object/mean.tif" --force -o "$T/b.hdr"
check "--force: warning naming both" grep -q "warning: --force: .*serial B.*serial A" "$T/err"
check "--force: cube written" test -s "$T/b.hdr"
expect_exit 0 "$KOGEI" classify --calib "$T/cam.json" --materials "$LIB" "$T/SB/captures/object/mean.tif" --force -o "$T/bl.hdr"
# The same camera (another session, another seed, another pixel format): accepted.
expect_exit 0 "$KOGEI" estimate --calib "$T/cam.json" "$T/SA/captures/object/mean.tif" -o "$T/a.hdr"
check "serial A: no refusal" sh -c "! grep -q 'warning\|not checked' '$T/err'"
check "serial A: the pixel format differs, noted" grep -q "note: .*same camera.*pixel format rgb16, calibrated in bayer16" "$T/err"
expect_exit 0 "$KOGEI" classify --calib "$T/cam.json" --materials "$LIB" "$T/SA/captures/object/mean.tif" -o "$T/al.hdr"
# An image from outside a session: unknown camera, a note.
expect_exit 0 "$KOGEI" estimate --calib "$T/cam.json" "$T/object.tif" -o "$T/o.hdr"
check "outside a session: not checked" grep -q "note: camera identity not checked: .*object.tif is not a capture of a kogei session" "$T/err"
# A calibration without identity (the chart read from outside the session): a note.
cp "$CHART" "$T/chart_copy.tif"
expect_exit 0 "$KOGEI" chart detect --layout "$LAYOUT" "$T/chart_copy.tif" -o "$T/plain.cgats"
check "outside a session: no CAMERA keywords" sh -c "! grep -q CAMERA_SERIAL '$T/plain.cgats'"
expect_exit 0 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/plain.cgats" -o "$T/plain.json"
check "camera.json without identity: null" sh -c "tr -d ' \n' < '$T/plain.json' | grep -q '\"camera\":null'"
expect_exit 0 "$KOGEI" estimate --calib "$T/plain.json" "$T/SB/captures/object/mean.tif" -o "$T/p.hdr"
check "calibration without identity: not checked" grep -q "note: camera identity not checked: .*plain.json records no camera identity" "$T/err"
# A camera file written before identities existed (no "camera" key) loads as unknown.
grep -v '^  "camera": null,$' "$T/plain.json" > "$T/older.json"
check "older file: no camera key" sh -c "! grep -q '\"camera\"' '$T/older.json'"
expect_exit 0 "$KOGEI" estimate --calib "$T/older.json" "$T/SB/captures/object/mean.tif" -o "$T/q.hdr"
check "older file: not checked" grep -q "note: camera identity not checked: .*older.json records no camera identity" "$T/err"
# A file of a capture the manifest does not list (an unfinished one) is refused.
mkdir -p "$T/S/captures/unfinished"
cp "$T/object.tif" "$T/S/captures/unfinished/mean.tif"
expect_exit 1 "$KOGEI" estimate --calib "$T/cam.json" "$T/S/captures/unfinished/mean.tif" -o "$T/u.hdr"
check "unfinished capture: named" grep -q "no capture named unfinished" "$T/err"

[ $fail = 0 ] && echo "camera-identity: ok"
exit $fail
