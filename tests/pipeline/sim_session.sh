#!/bin/sh
# A site session recorded with the sim devices, as an operator records one: the
# simulated scenes (the CIE test colour chart in its AprilTag frame under CIE A, and
# the library's materials on a black ground, both 800x600 through the demo's site
# camera), then kogei acquire of a dark, a flat, the chart and objects, and kogei
# measure of the chart with the simulated spectrophotometer. Sourced by the tests.
# Needs KOGEI and FIX (the source tree's fixtures/) set, colord-data, and tests/lib.sh
# sourced first.

SIM_CAMERA='format=bayer_rggb12&fullwell=20000&read=5&serial=site-1'
TCS=/usr/share/colord/ref/CIE-TCS.sp

# Skip the test unless the session can be simulated and processed: FLAG is 1 when
# kogei is built with libapriltag and OpenCV (chart tags, demosaicing); colord-data;
# python3 (PY) with MODULE.
sim_session_needs() { # FLAG [MODULE]
	kg_need "$1" "built without libapriltag or OpenCV (chart tags, demosaicing)"
	kg_need_tcs
	kg_python "${2:-}"
}

sim_scenes() { # DIR [CHART_TRUTH.cgats: each patch's pixel position, PIXEL_X PIXEL_Y]
	"$KOGEI" sim chart --layout cie-tcs-frame --spectra "$TCS" ${2:+--truth "$2"} \
		--camera "$FIX/demo/site_camera.csv" --illuminant A --tilt 25 --tilt-axis 120 \
		--rotate 5 --blur 1 --vignetting 0.1 --seed 2 --width 800 --height 600 --fov 40 \
		--fill 0.85 --paper 0.85 --ink 0.03 --background 0.2 --white-level 0.9 \
		--noise none --depth float -o "$1/chart.tif" >/dev/null &&
	"$KOGEI" sim image --materials default --camera "$FIX/demo/site_camera.csv" \
		--illuminant A --angle 30 --patch-size 40 --gap 10 --columns 5 --background 0 \
		--white-level 0.9 --size 800x600 --noise none --depth float \
		-o "$1/object.tif" --truth-labels "$1/object_truth.hdr" >/dev/null
}

# acquire SESSION KIND SCENE EXPOSURE_US [extra sim keys] [acquire options...]
sim_acquire() {
	s=$1 kind=$2 scene=$3 exp=$4 keys=${5:-}
	shift 4
	[ $# -gt 0 ] && shift
	"$KOGEI" acquire --camera "sim:$scene?$SIM_CAMERA$keys" --out "$s" --kind "$kind" \
		--frames 4 --exposure "$exp" --gain 0 "$@" >/dev/null
}

sim_measure() { # OUT.cgats
	"$KOGEI" measure --spectro "sim:$TCS" --chart cie-tcs-frame --yes -o "$1" >/dev/null 2>&1
}
