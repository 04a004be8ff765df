#!/bin/sh
# scripts/docs_console.sh [BUILD_DIR]: remake docs/console-*.png from a real run of the
# console in headless Chromium: the chart check, a capture and the session view from
# tests/console/test_console_browser.sh, and the live view of a 1024 x 768 sim camera
# at the end of bench/console_live.sh's measurement, its status line showing the rate
# and latency the page measured (its table into docs/bench/console-live.md). Runs in a
# private network namespace; needs chromium and python3-websocket.
set -eu
cd "$(dirname "$0")/.."
BUILD=${1:-build}
[ -x "$BUILD/cli/kogei" ] || { echo "docs_console: $BUILD/cli/kogei not built" >&2; exit 1; }
export KOGEI_SOURCE_ROOT="$(pwd)" KOGEI_CAMERA_DISCOVERY=none
shots=$(mktemp -d "${TMPDIR:-/tmp}/kg_docs_console_XXXXXX")
trap 'rm -rf "$shots"' EXIT
unshare -rn sh -c 'ip link set lo up; sh tests/console/test_console_browser.sh "$0" "$1"' \
	"$BUILD/cli/kogei" "$shots"
for v in chart capture session; do
	cp "$shots/console-$v.png" docs/
done
unshare -rn sh -c 'ip link set lo up; sh bench/console_live.sh "$0" "$1" 20 "$2"' \
	"$BUILD/cli/kogei" docs/bench/console-live.md docs/console-live.png
