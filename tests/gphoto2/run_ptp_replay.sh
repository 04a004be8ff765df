#!/bin/sh
# Synthesise the PTP replay and run one scenario of test_gphoto2_ptp inside umockdev-run.
# usage: run_ptp_replay.sh WRITE_DNG TEST_GPHOTO2_PTP config|capture|preview [WRITE_JPEG]
# WRITE_DNG writes the picture (libtiff), make_ptp_replay.py the device and the URBs
# (README.md); both go to a temporary folder, removed afterwards.
set -u
write_dng=$1 test=$2 scenario=$3 write_jpeg=${4:-}
command -v umockdev-run >/dev/null 2>&1 || { echo "SKIP: umockdev-run not installed"; exit 77; }
command -v python3 >/dev/null 2>&1 || { echo "SKIP: python3 not installed"; exit 77; }
command -v timeout >/dev/null 2>&1 || { echo "SKIP: timeout not installed"; exit 77; }
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$write_dng" "$tmp/picture.dng" || { echo "FAIL: cannot write the DNG"; exit 1; }
jpeg=
if [ -n "$write_jpeg" ]; then
	"$write_jpeg" "$tmp/liveview.jpg" || { echo "FAIL: cannot write the JPEG"; exit 1; }
	jpeg="$tmp/liveview.jpg"
fi
python3 "$here/make_ptp_replay.py" "$tmp/picture.dng" "$tmp" $jpeg ||
	{ echo "FAIL: cannot generate the replay"; exit 1; }
mkdir -p "$tmp/home/.gphoto" "$tmp/saved"
# libgphoto2 keeps property descriptions 2 s by default and fetches them again after:
# a whole session here keeps them (the replay holds each GetDevicePropDesc once, so
# the transactions must not depend on the clock). HOME also keeps libgphoto2's
# settings out of the user's.
printf 'ptp2=cachetime=3600\n' >"$tmp/home/.gphoto/settings"
export HOME="$tmp/home"
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0"
echo "replaying $scenario (transaction id, operation):"
sed 's/^/  /' "$tmp/ptp-$scenario.steps"
extra=""
[ "$scenario" = capture ] && extra="$tmp/picture.dng"
[ "$scenario" = preview ] && extra="$tmp/liveview.jpg"
timeout 60 umockdev-run --device "$tmp/ptp-$scenario.umockdev" \
	--ioctl "/dev/bus/usb/001/002=$tmp/ptp-$scenario.ioctl" -- \
	"$test" "$scenario" "$tmp" $extra </dev/null
rc=$?
[ "$rc" -eq 124 ] && echo "FAIL: timed out (a transaction the replay does not hold?)"
exit $rc
