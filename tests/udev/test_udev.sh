#!/bin/sh
# usage: test_udev.sh KOGEI_GEN_UDEV RULES KOGEI
# The checked-in rules match what kogei-gen-udev prints from the id tables, no rule
# opens a device to everyone, and `kogei devices` lists the spectrometer backends.
set -u
gen=$1 rules=$2 kogei=$3
tmp=$(mktemp -d) || exit 1
trap 'rm -rf "$tmp"' EXIT
fail=0

"$gen" > "$tmp/rules" || { echo "FAIL: kogei-gen-udev exited $?"; exit 1; }
if ! diff -u "$rules" "$tmp/rules"; then
	echo "FAIL: $rules is stale; regenerate: kogei-gen-udev > udev/70-kogei.rules"
	fail=1
fi
if grep -n '^[^#]*MODE="0666"' "$rules" "$tmp/rules"; then
	echo 'FAIL: MODE="0666" gives every user the device; use uaccess and a group'
	fail=1
fi
# Every rule: mode 0660, a group, and uaccess for the user at the seat.
grep -v '^#' "$rules" | grep -v '^$' > "$tmp/lines"
[ -s "$tmp/lines" ] || { echo "FAIL: $rules has no rules"; fail=1; }
while IFS= read -r line; do
	case $line in
	*'MODE="0660"'*'GROUP="'?*'"'*'TAG+="uaccess"'*) ;;
	*) echo "FAIL: rule without MODE=\"0660\", a GROUP and TAG+=\"uaccess\": $line"; fail=1 ;;
	esac
done < "$tmp/lines"
for m in 'ID_USB_INTERFACES}=="\*:ef0500:\*"' 'SUBSYSTEM=="video4linux"'; do
	grep -q "$m" "$tmp/rules" || { echo "FAIL: no camera rule matching $m"; fail=1; }
done
# meson install puts the rules into a udev rules directory.
installed=${KOGEI_BUILD_ROOT:-}/meson-info/intro-installed.json
if [ -f "$installed" ]; then
	grep -q '70-kogei.rules": "[^"]*/udev/rules.d/70-kogei.rules"' "$installed" ||
		{ echo "FAIL: $installed does not install 70-kogei.rules into .../udev/rules.d"; fail=1; }
else
	echo "note: $installed not found; install location not checked"
fi
if ! grep -q 'ATTRS{idVendor}=="2457", ATTRS{idProduct}=="101e"' "$tmp/rules"; then
	echo "FAIL: no rule for 2457:101e"
	fail=1
fi

"$kogei" devices > "$tmp/out" 2>&1
rc=$?
cat "$tmp/out"
[ $rc -eq 0 ] || { echo "FAIL: kogei devices exited $rc"; fail=1; }
for b in usbspec sim replay v4l2 aravis libcamera; do
	grep -q "^  $b " "$tmp/out" || { echo "FAIL: kogei devices does not list $b"; fail=1; }
done
grep -q '^attached spectrometers:' "$tmp/out" ||
	{ echo "FAIL: no attached spectrometers section"; fail=1; }
exit $fail
