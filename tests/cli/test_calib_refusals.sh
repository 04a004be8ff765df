#!/bin/sh
# Refuse rather than write a wrong result: a photograph without the chart, patches
# read in the wrong order, a chart detected with the wrong layout and a chart of only
# 3 patches give no calibration (exit 1, a message naming the file and the cause,
# nothing written). The charts are simulated (kogei sim chart / sim image) from the
# CIE 13.3 test colours of colord-data; the reference is the demo's reference camera.
# usage: test_calib_refusals.sh KOGEI SOURCE_ROOT HAVE_APRILTAG
set -u
. "$(dirname "$0")/../lib.sh"
. "$(dirname "$0")/demo_reference.sh"
KOGEI=$1
SRC=$2
kg_temp
# The reference: the demo's reference camera under D65 on the same 15 colours.
demo_reference "${3:-1}"

# A good site chart: another camera under A, tilted.
expect_exit 0 "$KOGEI" sim chart --layout "$LAYOUT" --spectra "$TCS" --camera "$D/site_camera.csv" \
	--illuminant A --tilt 20 --rotate 5 --width 800 --height 600 --noise 20000:5:12 \
	--depth 16 -o "$T/chart.tif"
expect_exit 0 "$KOGEI" chart detect --layout "$LAYOUT" "$T/chart.tif" -o "$T/good.cgats"
expect_exit 0 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/good.cgats" -o "$T/good.json"
good=$(sed -n 's/.*relative \([0-9.]*\).*/\1/p' "$T/out")
echo "good chart: relative residual $good"
check "a good chart's residual is reported" test -n "$good"

# 1. No chart: an object photograph (the 15 colours and the 10 materials as 24 tiles,
# 4 x 6 like a ColorChecker) has no tags, and the tagless fallback's box does not
# read as a ColorChecker in any turn: refused, no patch file.
expect_exit 0 "$KOGEI" sim image --spectra "$TCS" --materials "$SRC/fixtures/materials/default.json" \
	--camera "$D/site_camera.csv" --illuminant D65 --patch-size 60 --gap 12 --columns 6 \
	--background 0.2 --noise none --depth 16 -o "$T/object.tif"
CC=$SRC/fixtures/charts/colorchecker24-frame.json
expect_exit 1 "$KOGEI" chart detect --layout "$CC" "$T/object.tif" -o "$T/object.cgats"
check "no chart: the message names the image" grep -q "object.tif" "$T/err"
check "no chart: no tags" grep -q "no tag36h11 tags" "$T/err"
if grep -q "tagless detector" "$T/err"; then
	check "no chart: the tagless box does not read as the layout" \
		grep -q "do not read as layout colorchecker24-frame" "$T/err"
else
	echo "note: the tagless detector did not run or found nothing"; cat "$T/err"
fi
check "no chart: no patch file" test ! -e "$T/object.cgats"
# --min-tags given: tags only, no fallback.
expect_exit 1 "$KOGEI" chart detect --layout "$CC" --min-tags 2 "$T/object.tif" -o "$T/object.cgats"
check "--min-tags 2: no fallback" sh -c "! grep -q 'tagless\|mcc' '$T/err'"
check "--min-tags 2: no patch file" test ! -e "$T/object.cgats"

# 2a. Patches read in the wrong order (the chart turned 180 degrees: the values of
# the 15 rows reversed, ids kept): the residual is far above the limit.
awk '/^BEGIN_DATA[ \t\r]*$/ {d = 1; print; next} /^END_DATA[ \t\r]*$/ {
	for (i = 1; i <= n; i++) { split(row[i], a, " "); split(row[n + 1 - i], b, " ");
		line = a[1]; for (j = 2; j <= length(b); j++) line = line " " b[j]; print line }
	d = 0; print; next } d { row[++n] = $0; next } { print }' "$T/good.cgats" > "$T/turned.cgats"
expect_exit 1 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/turned.cgats" -o "$T/turned.json"
check "wrong order: the message names the file" grep -q "turned.cgats" "$T/err"
check "wrong order: relative residual above the limit" grep -q "relative residual.*above the limit of 10.0 %" "$T/err"
check "wrong order: worst patches" grep -q "Worst patches: TCS" "$T/err"
check "wrong order: nothing written" test ! -e "$T/turned.json"
# --max-residual overrides the limit.
expect_exit 0 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/turned.cgats" \
	--max-residual 2 -o "$T/turned.json"
expect_exit 1 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/good.cgats" \
	--max-residual 0.001 -o "$T/tight.json"
check "--max-residual 0.001 refuses the good chart" grep -q "above the limit of 0.1 %" "$T/err"
expect_exit 2 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/good.cgats" \
	--max-residual 0 -o "$T/tight.json"

# 2b. A wrong layout: the chart's own tags, its patches placed 14 mm right and 12 mm
# down, so every sampled region straddles two patches and the gap between them: all
# 15 flagged, none usable.
awk '/"id": "TCS/ { match($0, /"center_mm": \[[0-9.]+, [0-9.]+\]/); c = substr($0, RSTART + 14, RLENGTH - 15);
	split(c, xy, ", "); $0 = substr($0, 1, RSTART - 1) sprintf("\"center_mm\": [%.1f, %.1f]", xy[1] + 14, xy[2] + 12) substr($0, RSTART + RLENGTH) }
	/"chart_area_mm"/ { $0 = "  \"chart_area_mm\": [65.0, 35.0, 239.0, 157.0]," }
	/"name": "cie-tcs-frame"/ { $0 = "  \"name\": \"cie-tcs-frame-shifted\"," } { print }' "$LAYOUT" > "$T/shifted.json"
expect_exit 0 "$KOGEI" chart detect --layout "$T/shifted.json" "$T/chart.tif" -o "$T/shifted.cgats"
check "wrong layout: detection flags all 15" grep -q "15 patches flagged" "$T/err"
expect_exit 1 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/shifted.cgats" -o "$T/shifted_cam.json"
check "wrong layout: 15 of 15 flagged" grep -q "shifted.cgats: 15 of its 15 patches in common with the reference were flagged" "$T/err"
check "wrong layout: names them and why" grep -q "TCS01 (.*non-uniform" "$T/err"
check "wrong layout: nothing written" test ! -e "$T/shifted_cam.json"

# 2c. Some patches flagged: left out of M2, listed on stderr and in camera.json.
awk -v OFS=' ' '/^BEGIN_DATA[ \t\r]*$/ {d = 1; print; next} /^END_DATA[ \t\r]*$/ {d = 0} d && ($1 == "TCS02" || $1 == "TCS09") { $NF = 16 } { print }' \
	"$T/good.cgats" > "$T/two_flagged.cgats"
expect_exit 0 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/two_flagged.cgats" -o "$T/two.json"
check "flagged: note on stderr" grep -q "2 patches flagged by chart detection left out of M2: TCS02 (flags 16), TCS09 (flags 16)" "$T/err"
check "flagged: 13 patches used" grep -q "site calibration: 13 patches" "$T/out"
check "flagged: listed in camera.json" sh -c "tr -d ' \n' < '$T/two.json' | grep -q '\"flagged\":\[{\"id\":\"TCS02\",\"flags\":16},{\"id\":\"TCS09\",\"flags\":16}\]'"

# 2d. Exactly 3 usable patches: the residual is 0 whatever they are: refused unless
# --force, which warns.
ex=TCS01,TCS02,TCS04,TCS06,TCS07,TCS08,TCS10,TCS11,TCS12,TCS13,TCS14,TCS15
expect_exit 1 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/good.cgats" --exclude $ex -o "$T/three.json"
check "3 patches: cannot be checked" grep -q "only 3 usable patches (TCS03, TCS05, TCS09).*cannot be checked" "$T/err"
check "3 patches: nothing written" test ! -e "$T/three.json"
expect_exit 0 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/good.cgats" --exclude $ex --force -o "$T/three.json"
check "3 patches --force: warning" grep -q "warning: --force: M2 from exactly 3 patches" "$T/err"

[ $fail = 0 ] && echo "calib-refusals-cli: ok"
exit $fail
