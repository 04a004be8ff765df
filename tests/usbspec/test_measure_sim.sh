#!/bin/sh
# kogei measure with the sim spectrometer: single spot, a guided chart driven from
# standard input (redo, white again, quit, resume), and the failure exits.
set -u
. "$(dirname "$0")/../lib.sh"
kogei=$1
root=$KG_ROOT
spectra="$root/fixtures/usbspec/chart_spectra.cgats"
kg_temp
tmp=$T
ids=A01,A02,A03,A04,A05,A06,B01,B02,B03,B04,B05,B06

"$kogei" measure --spectro "sim:$spectra" --single --id A03 --yes -o "$tmp/one.cgats" 2>"$tmp/log"
check_eval "single: exit 0" '[ $? -eq 0 ]'
check_eval "single: serial keyword" 'grep -q "SERIAL_NUMBER \"SIM-chart_spectra.cgats\"" "$tmp/one.cgats"'
check_eval "single: integration keyword" 'grep -q "INTEGRATION_TIME_US \"100000\"" "$tmp/one.cgats"'
check_eval "single: A03 row" 'grep -q "^A03[[:space:]]" "$tmp/one.cgats"'

# Guided: dark, white, A01, A02, redo (A02 again), w (white again), A03, then quit.
printf '\n\nm\n\nr\nw\n\n\nq\n' | "$kogei" measure --spectro "sim:$spectra" --patches $ids \
	-o "$tmp/chart.cgats" 2>"$tmp/log"
rc=$?
check_eval "quit: exit 1 (got $rc)" '[ $rc -eq 1 ]'
check_eval "quit: no output" '[ ! -e "$tmp/chart.cgats" ]'
check_eval "quit: partial has 3 patches" '[ $(grep -c "^[AB]0[1-6][[:space:]]" "$tmp/chart.cgats.partial") -eq 3 ]'
check_eval "quit: redo prompt" 'grep -q "Put the probe on patch A02 again" "$tmp/log"'
check_eval "quit: white drift reported" 'grep -q "white reference changed by" "$tmp/log"'
check_eval "quit: progress" 'grep -q "\[3/12\] Put the probe on patch A03" "$tmp/log"'

"$kogei" measure --spectro "sim:$spectra" --patches $ids --yes -o "$tmp/chart.cgats" 2>"$tmp/log"
check_eval "partial without --resume refused" '[ $? -eq 1 ] && grep -q "add --resume" "$tmp/log"'

"$kogei" measure --spectro "sim:$spectra" --patches $ids --yes --resume --check-white \
	-o "$tmp/chart.cgats" 2>"$tmp/log"
check_eval "resume: exit 0" '[ $? -eq 0 ]'
check_eval "resume: starts at 4" 'grep -q "\[4/12\] Put the probe on patch A04" "$tmp/log"'
check_eval "resume: 12 patches" '[ $(grep -c "^[AB]0[1-6][[:space:]]" "$tmp/chart.cgats") -eq 12 ]'
check_eval "resume: partial removed" '[ ! -e "$tmp/chart.cgats.partial" ]'
check_eval "resume: final white drift" 'grep -q "drift over the chart" "$tmp/log"'
awk -v tol=0.01 -f "$root/tests/usbspec/compare_cgats.awk" "$spectra" "$tmp/chart.cgats"
check_eval "resume: reflectance within 0.01 of the spectra" '[ $? -eq 0 ]'

"$kogei" measure --spectro "sim:$spectra" --single --integration 3000 --yes \
	-o "$tmp/sat.cgats" 2>"$tmp/log"
rc=$?
check_eval "saturation refused: exit 1 (got $rc), no file" '[ $rc -eq 1 ] && [ ! -e "$tmp/sat.cgats" ]'
check_eval "saturation refused: the range and the remedy" \
	'grep -q "white reference: [0-9]* pixels saturated at [0-9.]*-[0-9.]* nm" "$tmp/log" &&
	 grep -q "shorten the integration time (--integration, now 3000 ms)" "$tmp/log"'

"$kogei" measure --spectro "sim:$spectra" --single --id NOPE --yes -o "$tmp/x.cgats" 2>"$tmp/log"
check_eval "unknown sample: exit 1" '[ $? -eq 1 ] && [ ! -e "$tmp/x.cgats" ]'
"$kogei" measure --spectro "bogus" --single -o "$tmp/x.cgats" 2>/dev/null
check_eval "bad URI: exit 1" '[ $? -eq 1 ]'
"$kogei" measure --spectro "sim:$spectra" -o "$tmp/x.cgats" 2>/dev/null
check_eval "no mode: exit 2" '[ $? -eq 2 ]'
"$kogei" measure --spectro "usbspec:2457:101e" --single --yes -o "$tmp/x.cgats" 2>"$tmp/log"
rc=$?
check_eval "no device: exit 3 (got $rc)" '[ $rc -eq 3 ] && [ ! -e "$tmp/x.cgats" ]'

[ $fail -eq 0 ] && echo "measure-sim: ok"
exit $fail
