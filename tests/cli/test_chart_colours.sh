#!/bin/sh
# Patches against the layout's colours (calib/chart_colours.c) through the real CLI:
# ColorChecker frames simulated through real camera sensitivities, then changed where
# the chart is (tests/chart_detect/paint_chart.py): cards of any grey over patches and
# patches painted another patch's colour are flagged (FLAGS 64) with their reason and
# nothing else is; a step in the light between patches (half the chart in shadow, a
# shadowed corner) is refused naming it, while a lamp's gradient and vignetting are
# not; a tagless ColorChecker on black paper with four patches painted its black has
# exactly those four flagged; clipped patches are still flagged clipped. A chart whose
# layout has no expected colours (the CIE test colours) with a card over a patch or
# one painted another's colour: calib camera leaves it out of M2 as not fitting.
# Reads the reference data set (kg_need_reference; skipped without it).
# usage: test_chart_colours.sh KOGEI SOURCE_ROOT HAVE_APRILTAG HAVE_MCC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
SRC=$2
HAVE_APRILTAG=${3:-1}
HAVE_MCC=${4:-1}
kg_need_reference "$SRC" charts/colorchecker24_babelcolor_avg.csv cameras/Nikon_D5100.csv \
	cameras/Canon_EOS_5D_Mark_II.csv
kg_need "$HAVE_APRILTAG" "built without libapriltag"
kg_python
kg_temp
SPECTRA=$REF/charts/colorchecker24_babelcolor_avg.csv
LAYOUT=$SRC/fixtures/charts/colorchecker24-frame.json
PAINT="$SRC/tests/chart_detect/paint_chart.py"

sim() { # NAME CAMERA ILLUMINANT [sim options...]
	n=$1 cam=$2 ill=$3
	shift 3
	"$KOGEI" sim chart --layout "$LAYOUT" --spectra "$SPECTRA" --camera "$REF/cameras/$cam.csv" \
		--illuminant "$ill" --width 1000 --height 750 --noise 20000:5:12 --blur 0.8 "$@" \
		-o "$T/$n.tif" --truth "$T/$n.truth" >/dev/null || { echo "FAIL: sim chart $n"; exit 1; }
}
# the ids of the patches whose FLAGS have bit B, space-separated
flagged() { # PATCHES.cgats B
	awk -v bit="$2" '/^BEGIN_DATA_FORMAT/ { f = 1; next } /^END_DATA_FORMAT/ { f = 0; next }
	f { for (i = 1; i <= NF; i++) if ($i == "FLAGS") fc = i; next }
	/^BEGIN_DATA$/ { d = 1; next } /^END_DATA$/ { d = 0 }
	d && int($fc / bit) % 2 == 1 { printf "%s%s", n++ ? " " : "", $1 }' "$1"
}
# detect BASE NAME 'IDS' [detect options...] after paint_chart.py OPS (in $OPS): exit 0 and
# exactly IDS flagged 64
detect() { # BASE NAME IDS [options]
	b=$1 n=$2 want=$3
	shift 3
	rm -f "$T/$n.cgats"
	if [ -n "$OPS" ]; then
		# shellcheck disable=SC2086
		"$PY" "$PAINT" "$T/$b.tif" "$T/$b.truth" "$LAYOUT" "$T/$n.tif" $OPS ||
			{ echo "FAIL: paint_chart $n"; fail=1; return; }
	elif [ "$b" != "$n" ]; then
		cp "$T/$b.tif" "$T/$n.tif"
	fi
	"$KOGEI" chart detect --layout "$LAYOUT" "$@" "$T/$n.tif" -o "$T/$n.cgats" \
		>"$T/$n.out" 2>"$T/$n.err"
	rc=$?
	got=$( [ -s "$T/$n.cgats" ] && flagged "$T/$n.cgats" 64)
	if [ $rc = 0 ] && [ "$got" = "$want" ]; then
		echo "ok: $n: flagged 64: '${got}'"
	else
		echo "FAIL: $n: exit $rc, flagged 64 '$got', expected exit 0 and '$want':"
		cat "$T/$n.err"; fail=1
	fi
}
# refused BASE NAME PATTERN: exit 1, the message matching PATTERN, no patch file
refused() { # BASE NAME PATTERN
	"$PY" "$PAINT" "$T/$1.tif" "$T/$1.truth" "$LAYOUT" "$T/$2.tif" $OPS ||
		{ echo "FAIL: paint_chart $2"; fail=1; return; }
	rm -f "$T/$2.cgats"
	"$KOGEI" chart detect --layout "$LAYOUT" "$T/$2.tif" -o "$T/$2.cgats" >"$T/$2.out" \
		2>"$T/$2.err"
	rc=$?
	if [ $rc = 1 ] && grep -q "$3" "$T/$2.err" && [ ! -e "$T/$2.cgats" ]; then
		echo "ok: $2: refused: $(grep -o 'falls by [^,]*' "$T/$2.err")"
	else
		echo "FAIL: $2: exit $rc, expected 1, '$3' and no patch file:"; cat "$T/$2.err"
		fail=1
	fi
}

# ---- a framed chart, tags found ------------------------------------------------------
sim a Nikon_D5100 D65 --tilt 20 --rotate 10 --seed 3
OPS=
detect a clean ""
check "clean: the check ran" grep -q "24 patches judged, 0 flagged" "$T/clean.err"
check "clean: COLOUR_CHECK keyword" grep -q '^COLOUR_CHECK "24 patches judged, 0 flagged' \
	"$T/clean.cgats"
# the simulator's own dark card (reflectance 0.04) over the first two patches
sim card Nikon_D5100 D65 --tilt 20 --rotate 10 --seed 3 --occlude patches
detect card card "A01 A02"
check "card: the reason in the warning" grep -q \
	"A01: colour does not fit the layout's .*covered, painted over or in a shadow" "$T/card.err"
check "card: the reason in the patch's flags" test "$(flagged "$T/card.cgats" 64)" = "A01 A02"
# cards of every grey, a patch painted another's colour
OPS="cover:B04+B05:0.005"; detect a black-card "B04 B05"
OPS="cover:C03:0.18"; detect a grey-card "C03"
OPS="cover:D03:0.85"; detect a white-card "D03"
OPS="cover:A05:0.5 cover:C06:0.03"; detect a two-cards "A05 C06"
OPS="paint:A01:A02"; detect a painted-light-skin "A01"
OPS="paint:D04:D03"; detect a painted-grey "D04"
OPS="paint:B05:C06"; detect a painted-cyan "B05"
# light: steps between patches refused, gradients not
OPS="light:60:30:200:250:0.05"; refused a left-dark "falls by 95 % from its right to its left half"
OPS="light:60:30:340:138:0.5"; refused a top-half "falls by 50 % from its bottom to its top half"
OPS="ramp:1:0.3"; detect a ramp ""
OPS=
sim vignetted Nikon_D5100 D65 --tilt 20 --rotate 10 --seed 3 --vignetting 0.6
detect vignetted vignetted ""
# clipped patches stay clipped, and are not judged against the colours
sim bright Canon_EOS_5D_Mark_II A --tilt 10 --seed 5 --white-level 1.6
detect bright bright ""
clipped=$(flagged "$T/bright.cgats" 1)
check_eval "bright: the white and light grey flagged clipped ('$clipped')" \
	'case " $clipped " in *" D01 "*) true ;; *) false ;; esac'

# ---- a tagless ColorChecker on black paper, four patches painted its black -------------
if [ "$HAVE_MCC" = 1 ]; then
	sim black Canon_EOS_5D_Mark_II A --tilt 15 --rotate 5 --seed 4 --paper 0.03
	OPS="paint:A03:D06 paint:B05:D06 paint:C02:D06 paint:D02:D06"
	detect black black4 "A03 B05 C02 D02" --tagless
else
	echo "skip: the tagless case (built without OpenCV mcc)"
fi
# ---- a layout without expected colours: the site fit leaves a covered patch out -------
TCS=/usr/share/colord/ref/CIE-TCS.sp
TL=$SRC/fixtures/demo/cie-tcs-frame.json
if [ -r "$TCS" ]; then
	tcs() { # NAME CAMERA ILLUMINANT [sim options]
		n=$1 cam=$2 ill=$3
		shift 3
		"$KOGEI" sim chart --layout "$TL" --spectra "$TCS" --camera "$SRC/fixtures/demo/$cam" \
			--illuminant "$ill" --width 1000 --height 750 --noise 20000:5:12 "$@" \
			-o "$T/$n.tif" --truth "$T/$n.truth" >/dev/null &&
		"$KOGEI" chart detect --layout "$TL" "$T/$n.tif" -o "$T/$n.cgats" 2>/dev/null ||
			{ echo "FAIL: the CIE test colours chart $n"; exit 1; }
	}
	tcs tref reference_camera.csv D65
	"$KOGEI" calib reference --spectra "$TCS" --rgb "$T/tref.cgats" -o "$T/tref.json" \
		>/dev/null 2>&1 || { echo "FAIL: calib reference on the CIE test colours"; exit 1; }
	tcs tsite site_camera.csv A --tilt 15 --seed 5
	for op in none cover:TCS05:0.5 cover:TCS03+TCS04:0.2 paint:TCS02:TCS09 cover:TCS12:0.03; do
		want=$(echo "$op" | sed -n 's/^[a-z]*:\([A-Z0-9+]*\):.*/\1/p' | tr '+' ' ')
		if [ "$op" = none ]; then
			cp "$T/tsite.cgats" "$T/tp.cgats"
		else
			# shellcheck disable=SC2086
			"$PY" "$PAINT" "$T/tsite.tif" "$T/tsite.truth" "$TL" "$T/tp.tif" $op &&
			"$KOGEI" chart detect --layout "$TL" "$T/tp.tif" -o "$T/tp.cgats" 2>/dev/null ||
				{ echo "FAIL: $op: detection"; fail=1; continue; }
		fi
		"$KOGEI" calib camera --reference "$T/tref.json" --rgb "$T/tp.cgats" -o "$T/tp.json" \
			>"$T/tp.out" 2>"$T/tp.err"
		rc=$?
		got=$("$PY" -c 'import json, sys
s = json.load(open(sys.argv[1]))["site"]
print(" ".join(f["id"] for f in s["flagged"] if f["flags"] == 64))' "$T/tp.json" 2>/dev/null)
		if [ $rc = 0 ] && [ "$got" = "$want" ]; then
			echo "ok: CIE test colours, $op: left out of M2 as not fitting: '$got'"
		else
			echo "FAIL: CIE test colours, $op: exit $rc, left out '$got', expected exit 0 and '$want':"
			cat "$T/tp.err"; fail=1
		fi
	done
else
	echo "skip: the CIE test colours ($TCS missing: package colord-data)"
fi
exit $fail
