#!/bin/sh
# The gphoto2 backend with no camera attached, and `kogei devices`.
# usage: test_devices.sh KOGEI TEST_GPHOTO2
# 1. enumeration inside an empty umockdev testbed (no USB device at all): nothing
#    reported, no note; without umockdev, on this machine: no note, entries well formed
# 2. `kogei devices` (KOGEI_CAMERA_DISCOVERY=none) lists the gphoto2 backend, leaves no
#    gphoto2 note, and ends in time
# 3. with the synthesised PTP camera of make_ptp_replay.py in the testbed, `kogei
#    devices` lists it as gphoto2:USB PTP Class Camera at usb:001,002 (autodetection
#    reads the device descriptors only: no transfer is made)
# 4. a libgphoto2 whose ptpip library would browse mDNS is not scanned with
#    KOGEI_CAMERA_DISCOVERY=none
set -u
kogei=$1 test=$2
here=$(cd "$(dirname "$0")" && pwd)
export KOGEI_CAMERA_DISCOVERY=none
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export HOME="$tmp"
fail=0
if command -v umockdev-run >/dev/null 2>&1; then
	umockdev-run -- "$test" enumerate none || fail=1
else
	"$test" enumerate any || fail=1
fi

echo "kogei devices lists the gphoto2 backend"
timeout 60 "$kogei" devices >"$tmp/devices" 2>&1 </dev/null
rc=$?
sed 's/^/  /' "$tmp/devices"
[ "$rc" -eq 0 ] || { echo "FAIL: kogei devices exited $rc"; fail=1; }
grep -q '^  gphoto2  *tethered' "$tmp/devices" || { echo "FAIL: no gphoto2 backend line"; fail=1; }
if grep -q '^  gphoto2: ' "$tmp/devices"; then echo "FAIL: a gphoto2 note"; fail=1; fi

if command -v umockdev-run >/dev/null 2>&1 && command -v python3 >/dev/null 2>&1; then
	echo "kogei devices with the synthesised PTP camera attached"
	: >"$tmp/none.dng"
	python3 "$here/make_ptp_replay.py" "$tmp/none.dng" "$tmp" || fail=1
	timeout 60 umockdev-run --device "$tmp/ptp-config.umockdev" -- "$kogei" devices \
		>"$tmp/devices2" 2>&1 </dev/null
	sed -n '/^cameras:/,/^$/p' "$tmp/devices2" | sed 's/^/  /'
	grep -q '^  gphoto2:USB PTP Class Camera .*USB PTP at usb:001,002' "$tmp/devices2" ||
		{ echo "FAIL: the PTP camera is not listed"; fail=1; }
else
	echo "SKIP (part 3): umockdev-run or python3 missing"
fi
echo "a libgphoto2 whose ptpip I/O library links libdns_sd (Bonjour) is not scanned with"
echo "KOGEI_CAMERA_DISCOVERY=none (a stand-in library in IOLIBS; nothing is loaded)"
mkdir "$tmp/iolibs"
printf 'stand-in: NEEDED libdns_sd.so.1\n' >"$tmp/iolibs/ptpip.so"
IOLIBS="$tmp/iolibs" timeout 60 "$kogei" devices >"$tmp/devices3" 2>&1 </dev/null
grep '^  gphoto2: ' "$tmp/devices3" | sed 's/^/  /'
grep -q '^  gphoto2: not scanned: .*mDNS' "$tmp/devices3" ||
	{ echo "FAIL: no note that gphoto2 was not scanned"; fail=1; }
[ "$fail" -eq 0 ] && echo "all checks passed"
exit $fail
