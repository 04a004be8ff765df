#!/bin/sh
# The console's live view as an operator sees it: previews per second and latency in
# headless Chromium from sim cameras (bench/console_live.py; docs/console.md,
# "Performance"). A benchmark, not a test: it asserts nothing about speed.
#
#   bench/console_live.sh KOGEI OUT.md [SECONDS [SHOT.png]]
#
# SHOT.png: a screenshot of the page of the 1024 x 768 camera at the end of its
# measurement (scripts/docs_console.sh makes docs/console-live.png so).
# Run it inside a private network namespace (bench/run_all.sh does:
# unshare -rn sh -c 'ip link set lo up; ...'). Without chromium or python3-websocket it
# writes a note saying so into OUT.md.
set -u
kogei=$1 out=$2 seconds=${3:-20} shot=${4:-}
here=$(cd "$(dirname "$0")" && pwd)
# tests/chromium.sh exits 77 when chromium or python3-websocket is missing
( . "$here/../tests/chromium.sh" >/dev/null ) || {
	echo "(not measured: chromium or python3-websocket missing)" > "$out"
	exit 0
}
. "$here/../tests/chromium.sh"
work=$(mktemp -d "${TMPDIR:-/tmp}/kg_bench_live_XXXXXX") || exit 1
trap 'chromium_cleanup; rm -rf "$work"' EXIT
chromium_start
KOGEI_CAMERA_DISCOVERY=none "$python" "$here/console_live.py" --kogei "$kogei" \
	--devtools "$devtools" --work "$work" --seconds "$seconds" -o "$out" ${shot:+--shot "$shot"}
