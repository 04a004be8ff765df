#!/bin/sh
# scripts/docs_console.sh [BUILD_DIR]: remake docs/console-*.png from a real run of the
# console in headless Chromium (tests/console/test_console_browser.sh with the
# screenshots into docs/): the live view of a 1024 x 768 sim camera with the rate and
# latency the page measured, the chart check, a capture and the session view. Runs in
# a private network namespace; needs chromium and python3-websocket.
set -eu
cd "$(dirname "$0")/.."
BUILD=${1:-build}
[ -x "$BUILD/cli/kogei" ] || { echo "docs_console: $BUILD/cli/kogei not built" >&2; exit 1; }
export KOGEI_SOURCE_ROOT="$(pwd)" KOGEI_CAMERA_DISCOVERY=none
unshare -rn sh -c 'ip link set lo up; sh tests/console/test_console_browser.sh "$0" docs' \
	"$BUILD/cli/kogei"
