#!/bin/sh
# Replay one fixtures/usbspec/<scenario> through the real libusb under umockdev-run and
# check `kogei measure`'s exit status, its messages, and its output file.
# usage: run_scenario.sh KOGEI SCENARIO EXPECTED_EXIT PATTERN [measure args...]
# "@OUT@" in the arguments is replaced by a temporary output path. With exit 0 and an
# expected.cgats in the fixture, the output must match it within 0.005; with any other
# exit, no output file may exist.
set -u
kogei=$1 scenario=$2 want=$3 pattern=$4
shift 4
command -v umockdev-run >/dev/null 2>&1 || { echo "SKIP: umockdev-run not installed"; exit 77; }
command -v timeout >/dev/null 2>&1 || { echo "SKIP: timeout not installed"; exit 77; }
here=$(cd "$(dirname "$0")" && pwd)
fix="$here/../../fixtures/usbspec/$scenario"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
out="$tmp/out.cgats"
args=""
for a in "$@"; do
	[ "$a" = "@OUT@" ] && a=$out
	args="$args '$a'"
done
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0"
# KOGEI_TEST_PRELOAD: a shim in front of libusb for kogei only (hold_transfer_preload).
preload=""
# It is added after umockdev's own preload, which umockdev-run has set by then.
[ -n "${KOGEI_TEST_PRELOAD:-}" ] &&
	preload="sh -c 'LD_PRELOAD=\"\$LD_PRELOAD:\$0\" exec \"\$@\"' '${KOGEI_TEST_PRELOAD}'"
eval timeout 15 umockdev-run --device "'$fix/device'" \
	--ioctl "/dev/bus/usb/001/002='$fix/capture.ioctl'" -- $preload "'$kogei'" measure $args \
	>"$tmp/log" 2>&1 </dev/null
rc=$?
cat "$tmp/log"
fail=0
if [ "$rc" -ne "$want" ]; then echo "FAIL: exit $rc, expected $want"; fail=1; fi
if ! grep -q -- "$pattern" "$tmp/log"; then echo "FAIL: no message matching '$pattern'"; fail=1; fi
if [ "$want" -ne 0 ] && [ -e "$out" ]; then echo "FAIL: output written despite failure"; fail=1; fi
if [ "$want" -eq 0 ] && [ -f "$fix/expected.cgats" ]; then
	awk -v tol=0.005 -f "$here/compare_cgats.awk" "$fix/expected.cgats" "$out" || {
		echo "FAIL: reflectance differs from $fix/expected.cgats"; fail=1; }
fi
[ "$fail" -eq 0 ] && echo "$scenario: ok"
exit $fail
