#!/bin/sh
# kogei and ArgyllCMS's spec2cie read each other's spectral CGATS unchanged and agree on
# XYZ within 0.01 (and 0.01 dE76) on the Y = 100 scale:
# - colord's reflectance references (ref/*.sp: CIE-TCS.sp, 360-830 nm): `kogei spectra
#   xyz` integrating the file's whole range, under D65 and A (spec2cie -i D65|A; it
#   needs MEAS_TYPE, which the colord files lack, so a copy gets that one line);
# - a kogei file: `kogei measure` output goes to spec2cie as written, against
#   `kogei spectra xyz --range observer` (spec2cie holds end values over 360-830 nm);
# - Argyll files: spec2cie's SPECT output (percent, no SPECTRAL_NORM) and Argyll's own
#   SOtele.sp (SPECTRAL_NORM 100) read by kogei with the right scale.
# Skipped (77) without spec2cie (package argyll) or colord-data.
# usage: test_spec2cie.sh KOGEI SOURCE_ROOT
set -u
KOGEI=$1
here=$2/tests/cli
tcs=/usr/share/colord/ref/CIE-TCS.sp
command -v spec2cie >/dev/null 2>&1 || { echo "SKIP: spec2cie (ArgyllCMS) not installed"; exit 77; }
[ -f "$tcs" ] || { echo "SKIP: $tcs absent (colord-data)"; exit 77; }
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail=0
run() { # command...: must exit 0
	"$@" >"$T/log" 2>&1 || { echo "FAIL: '$*' exited $?"; cat "$T/log"; fail=1; }
}
compare() { # what, scale, kogei xyz, spec2cie output
	awk -v tol=0.01 -v scale="$2" -v what="$1" -f "$here/compare_spec2cie.awk" "$3" "$4" || fail=1
}

# colord's reflectances: every ref/*.sp that is not a power distribution (fractions;
# spec2cie takes them as percent: scale 100).
for sp in /usr/share/colord/ref/*.sp; do
	grep -q -i -E 'Spectral Power|MEAS_TYPE.*EMISSION' "$sp" && continue
	b=$(basename "$sp" .sp)
	awk 'NR == 1 { print; print "MEAS_TYPE \"REFLECTIVE\""; next } { print }' "$sp" >"$T/$b.sp"
	first=$(awk '$1 == "SPECTRAL_START_NM" { gsub(/"/, "", $2); print $2 + 0 }' "$sp")
	last=$(awk '$1 == "SPECTRAL_END_NM" { gsub(/"/, "", $2); print $2 + 0 }' "$sp")
	for ill in D65 A; do
		run spec2cie -n -i $ill "$T/$b.sp" "$T/${b}_$ill.sp"
		run "$KOGEI" spectra xyz "$sp" --illuminant $ill -o "$T/k_${b}_$ill.cgats"
		grep -q "INTEGRATION_RANGE_NM \"$first-$last\"" "$T/k_${b}_$ill.cgats" ||
			{ echo "FAIL: $b.sp under $ill: INTEGRATION_RANGE_NM is not $first-$last"; fail=1; }
		compare "colord $b.sp under $ill, file range $first-$last nm" 100 \
			"$T/k_${b}_$ill.cgats" "$T/${b}_$ill.sp"
	done
done

# A kogei file, as `kogei measure` writes it, straight into spec2cie.
run "$KOGEI" measure --spectro "sim:$tcs" --patches TCS01,TCS02,TCS09,TCS12 --yes \
	-o "$T/measured.cgats"
for ill in D65 A; do
	run spec2cie -i $ill "$T/measured.cgats" "$T/measured_$ill.sp"
	run "$KOGEI" spectra xyz "$T/measured.cgats" --illuminant $ill --range observer \
		-o "$T/k_measured_$ill.cgats"
	compare "kogei measure file under $ill, spec2cie as written" 1 \
		"$T/k_measured_$ill.cgats" "$T/measured_$ill.sp"
done

# spec2cie's own output of that file: SPECT with MEAS_TYPE, the spectra in percent and
# no SPECTRAL_NORM. kogei must read percent (today's fractions would give X ~ 3000).
grep -q SPECTRAL_NORM "$T/measured_D65.sp" && echo "note: spec2cie kept SPECTRAL_NORM"
sed '/SPECTRAL_NORM/d' "$T/measured_D65.sp" >"$T/argyll_percent.sp"
run "$KOGEI" spectra xyz "$T/argyll_percent.sp" --illuminant D65 --range observer \
	-o "$T/k_argyll_percent.cgats"
compare "spec2cie output in percent read by kogei" 1 "$T/k_argyll_percent.cgats" \
	"$T/measured_D65.sp"

# An ArgyllCMS reference file: SOtele.sp, SPECTRAL_NORM 100, 380-730 nm.
so=/usr/share/color/argyll/ref/SOtele.sp
if [ -f "$so" ]; then
	run spec2cie -i D65 "$so" "$T/sotele.sp"
	run "$KOGEI" spectra xyz "$so" --illuminant D65 --range observer -o "$T/k_sotele.cgats"
	compare "argyll-ref SOtele.sp (SPECTRAL_NORM 100)" 1 "$T/k_sotele.cgats" "$T/sotele.sp"
else
	echo "note: $so absent (argyll-ref): not checked"
fi
exit $fail
