#!/bin/sh
# test_console_browser.sh KOGEI [SHOTDIR]
# The operator's console in headless Chromium (console_browser.py, over the Chrome
# DevTools Protocol): a sim session, the live view, clipping, chart check, a dark
# capture from the page, the session view, the token and path traversal. Screenshots
# of each view go to SHOTDIR (default $KOGEI_BUILD_ROOT/tests/console; docs/console-*.png
# are made with SHOTDIR=docs). Exit 77 when chromium or python3-websocket is missing.
set -u
kogei=$1 shots=${2:-${KOGEI_BUILD_ROOT:-.}/tests/console}
here=$(cd "$(dirname "$0")" && pwd)
. "$here/../chromium.sh"
work=$(mktemp -d "${TMPDIR:-/tmp}/kg_console_browser_XXXXXX") || exit 1
trap 'chromium_cleanup; rm -rf "$work"' EXIT
mkdir -p "$shots" || exit 1
tcs=/usr/share/colord/ref/CIE-TCS.sp
[ -f "$tcs" ] || { echo "SKIP: $tcs missing (colord-data)"; exit 77; }
"$kogei" sim chart --layout cie-tcs-frame --spectra "$tcs" \
	--camera "$KOGEI_SOURCE_ROOT/fixtures/demo/site_camera.csv" --illuminant A --tilt 25 \
	--tilt-axis 120 --rotate 5 --blur 1 --seed 2 --width 800 --height 600 --fov 40 \
	--fill 0.85 --paper 0.85 --ink 0.03 --background 0.2 --white-level 0.9 --noise none \
	--depth float -o "$work/chart.tif" >/dev/null || { echo "FAIL: kogei sim chart"; exit 1; }
chromium_start
"$python" "$here/console_browser.py" "$kogei" "$devtools" "$work" "$shots" "$work/chart.tif"
