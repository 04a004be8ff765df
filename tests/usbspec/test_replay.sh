#!/bin/sh
# kogei measure --record and the replay: spectrometer: a sim run recorded and replayed
# gives the same data rows bit for bit; a replay asked for other reads, a recording
# cut short and a replay that runs out of reads give their errors; an aborted or failed
# run still leaves its recording. With umockdev, the USB reflectance scenario is
# recorded through libusb and replayed without it.
set -u
. "$(dirname "$0")/../lib.sh"
kogei=$1
root=$KG_ROOT
spectra="$root/fixtures/usbspec/chart_spectra.cgats"
kg_temp
tmp=$T
# The data rows of a CGATS file (everything from BEGIN_DATA on).
data() { sed -n '/^BEGIN_DATA$/,$p' "$1"; }
same_data() { [ -s "$1" ] && [ -s "$2" ] && data "$1" >"$tmp/d1" && data "$2" >"$tmp/d2" &&
	[ -s "$tmp/d1" ] && cmp -s "$tmp/d1" "$tmp/d2"; }
kw() { grep "^$2 " "$1"; }
ids=A01,A02,B03
run() { "$kogei" measure --average 2 --yes "$@" 2>"$tmp/log"; }

# Record (2 scans: dark 1-2, white 3-4, A01 5-6, A02 7-8, B03 9-10).
run --spectro "sim:$spectra" --patches $ids --record "$tmp/rec" -o "$tmp/sim.cgats"
check_eval "record: exit 0" '[ $? -eq 0 ]'
check_eval "record: 10 reads" 'grep -q "^end 10$" "$tmp/rec" && [ $(grep -c "^read " "$tmp/rec") -eq 10 ]'
check_eval "record: reported" 'grep -q "recorded 10 raw reads in" "$tmp/log"'
check_eval "record: read 9 is B03" 'grep -q "^read 9 100000 B03$" "$tmp/rec"'
check_eval "record: no temporary left" '[ $(ls "$tmp" | grep -c "rec.tmp") -eq 0 ]'

# Replay: the same data, instrument, serial; re-recording gives the same reads.
run --spectro "replay:$tmp/rec" --patches $ids --record "$tmp/rec2" -o "$tmp/replay.cgats"
check_eval "replay: exit 0" '[ $? -eq 0 ]'
check_eval "replay: data rows bit-identical" 'same_data "$tmp/sim.cgats" "$tmp/replay.cgats"'
for k in INSTRUMENT SERIAL_NUMBER INTEGRATION_TIME_US SCANS_AVERAGED; do
	check_eval "replay: $k kept" '[ "$(kw "$tmp/sim.cgats" $k)" = "$(kw "$tmp/replay.cgats" $k)" ]'
done
check_eval "replay: re-recording has the same reads" \
	'[ "$(grep -v "^backend" "$tmp/rec")" = "$(grep -v "^backend" "$tmp/rec2")" ]'

# Single spot.
run --spectro "sim:$spectra" --single --id A03 --record "$tmp/one.rec" -o "$tmp/one.cgats"
check_eval "single: recorded" '[ $? -eq 0 ] && grep -q "^end 6$" "$tmp/one.rec"'
run --spectro "replay:$tmp/one.rec" --single --id A03 -o "$tmp/one-replay.cgats"
check_eval "single: replay identical" '[ $? -eq 0 ] && same_data "$tmp/one.cgats" "$tmp/one-replay.cgats"'

# Mismatches name the read and what the recording expects; exit 1, no output.
run --spectro "replay:$tmp/rec" --patches A01,A03,B03 -o "$tmp/m1.cgats"
rc=$?
check_eval "target mismatch: exit 1 (got $rc)" '[ $rc -eq 1 ] && [ ! -e "$tmp/m1.cgats" ]'
check_eval "target mismatch: message" \
	'grep -q "read 7: the recording expects target .A02. at 100000 us, the measurement asked for target .A03. at 100000 us" "$tmp/log"'
run --spectro "replay:$tmp/rec" --patches $ids --integration 50 -o "$tmp/m2.cgats"
rc=$?
check_eval "integration mismatch: exit 1 (got $rc)" '[ $rc -eq 1 ] && [ ! -e "$tmp/m2.cgats" ]'
check_eval "integration mismatch: message" \
	'grep -q "read 1: the recording expects target .dark. at 100000 us, the measurement asked for target .dark. at 50000 us" "$tmp/log"'
"$kogei" measure --spectro "replay:$tmp/rec" --patches $ids --average 1 --yes \
	-o "$tmp/m3.cgats" 2>"$tmp/log"
check_eval "averaging mismatch: read 2" '[ $? -eq 1 ] && grep -q "read 2: the recording expects target .dark." "$tmp/log"'

# Running out of reads is a device that stopped answering: exit 3, no output, and the
# recording of that failed run keeps what was read.
run --spectro "replay:$tmp/rec" --patches $ids,B04 --record "$tmp/fail.rec" -o "$tmp/out.cgats"
rc=$?
check_eval "out of reads: exit 3 (got $rc)" '[ $rc -eq 3 ] && [ ! -e "$tmp/out.cgats" ]'
check_eval "out of reads: message" \
	'grep -q "read 11 (target .B04. at 100000 us) asked for, but the recording ends after 10 reads" "$tmp/log"'
check_eval "failed run: recording of 10 reads" 'grep -q "^end 10$" "$tmp/fail.rec"'

# A file cut short (mid-read, or without its end line) is refused at open: exit 1.
head -c 30000 "$tmp/rec" >"$tmp/cut.rec"
run --spectro "replay:$tmp/cut.rec" --patches $ids -o "$tmp/c1.cgats"
check_eval "cut mid-read: exit 1" '[ $? -eq 1 ] && grep -q "raw counts: the recording is cut short" "$tmp/log"'
grep -v "^end" "$tmp/rec" >"$tmp/noend.rec"
run --spectro "replay:$tmp/noend.rec" --patches $ids -o "$tmp/c2.cgats"
check_eval "no end line: exit 1" '[ $? -eq 1 ] && grep -q "no .end. line after 10 reads" "$tmp/log"'
sed 's/^pixels 2048$/pixels 2047/' "$tmp/rec" >"$tmp/px.rec"
run --spectro "replay:$tmp/px.rec" --patches $ids -o "$tmp/c3.cgats"
check_eval "wrong pixel count: exit 1" '[ $? -eq 1 ] && grep -q "read 1: expected 2047 raw counts" "$tmp/log"'
run --spectro "replay:$tmp/missing.rec" --patches $ids -o "$tmp/c4.cgats"
check_eval "missing recording: exit 1" '[ $? -eq 1 ] && grep -q "missing.rec: cannot open" "$tmp/log"'

# An aborted run (the operator quits after A01) leaves its recording; replaying it with
# the same answers gives the same partial file.
printf '\n\n\nq\n' | "$kogei" measure --spectro "sim:$spectra" --patches $ids --average 2 \
	--record "$tmp/quit.rec" -o "$tmp/q1.cgats" 2>"$tmp/log"
check_eval "aborted: exit 1 and recording of 6 reads" '[ $? -eq 1 ] && grep -q "^end 6$" "$tmp/quit.rec"'
printf '\n\n\nq\n' | "$kogei" measure --spectro "replay:$tmp/quit.rec" --patches $ids \
	--average 2 -o "$tmp/q2.cgats" 2>"$tmp/log"
check_eval "aborted: replayed partial identical" \
	'[ $? -eq 1 ] && same_data "$tmp/q1.cgats.partial" "$tmp/q2.cgats.partial"'

# Optional: the USB reflectance scenario through libusb under umockdev, recorded, then
# replayed without the device.
fix="$root/fixtures/usbspec/reflectance"
if command -v umockdev-run >/dev/null 2>&1; then
	ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0" \
	umockdev-run --device "$fix/device" --ioctl "/dev/bus/usb/001/002=$fix/capture.ioctl" -- \
		"$kogei" measure --spectro usbspec:2457:1022 --single --yes --average 2 \
		--record "$tmp/usb.rec" -o "$tmp/usb.cgats" </dev/null >"$tmp/log" 2>&1
	rc=$?
	if [ $rc -ne 0 ] && grep -q "not built into" "$tmp/log"; then
		echo "SKIP (part): usbspec backend not built"
	else
		check_eval "usb record: exit 0 (got $rc)" '[ $rc -eq 0 ] && grep -q "^model USB4000$" "$tmp/usb.rec"'
		run --spectro "replay:$tmp/usb.rec" --single -o "$tmp/usb-replay.cgats"
		check_eval "usb replay: identical" '[ $? -eq 0 ] && same_data "$tmp/usb.cgats" "$tmp/usb-replay.cgats"'
		check_eval "usb replay: serial" '[ "$(kw "$tmp/usb.cgats" SERIAL_NUMBER)" = "$(kw "$tmp/usb-replay.cgats" SERIAL_NUMBER)" ]'
	fi
else
	echo "SKIP (part): umockdev-run not installed"
fi

[ $fail -eq 0 ] && echo "replay: ok"
exit $fail
