#!/bin/sh
# report_browser.sh REPORT.html SHOT.png [MAX_HEIGHT]
#
# Open an operator's report in headless Chromium and check it as a reader's browser
# sees it (report_browser.py, over the Chrome DevTools Protocol): no request leaves
# the file (only data: and file: URLs, none failing), no console error, every section
# has its heading, every image decodes; then save a screenshot of the page (at most
# MAX_HEIGHT CSS pixels tall, default the whole page) to SHOT.png and check it decodes.
# Works on any report.html, e.g. the one `kogei process` writes.
# Exit 0 pass, 1 fail, 2 usage, 77 when chromium or python3-websocket is missing.
set -u
if [ $# -lt 2 ] || [ $# -gt 3 ]; then
	echo "usage: $0 REPORT.html SHOT.png [MAX_HEIGHT]" >&2
	exit 2
fi
report=$1 shot=$2 max_height=${3:-0}
[ -f "$report" ] || { echo "$report: no such file" >&2; exit 1; }
chromium=${CHROMIUM:-$(command -v chromium || command -v chromium-browser || true)}
if [ -z "$chromium" ]; then
	echo "SKIP: chromium is not installed (Debian package chromium)"
	exit 77
fi
# The first Python that has the websocket module: $PYTHON, python3 on the PATH (which
# may be a private installation), then the system's, where python3-websocket goes.
python=
for p in ${PYTHON:-} python3 /usr/bin/python3; do
	if "$p" -c 'import websocket' 2>/dev/null; then
		python=$p
		break
	fi
done
if [ -z "$python" ]; then
	echo "SKIP: python3-websocket is not installed (no Python here imports websocket)"
	exit 77
fi
here=$(cd "$(dirname "$0")" && pwd)
profile=$(mktemp -d "${TMPDIR:-/tmp}/kg_chromium_XXXXXX") || exit 1
pid=
cleanup() {
	# Only the Chromium started here: its own process group (setsid), by its id.
	if [ -n "$pid" ]; then
		kill -TERM "-$pid" 2>/dev/null
		i=0
		while kill -0 "$pid" 2>/dev/null && [ $i -lt 50 ]; do
			sleep 0.1
			i=$((i + 1))
		done
		kill -KILL "-$pid" 2>/dev/null
		wait "$pid" 2>/dev/null
	fi
	rm -rf "$profile"
}
trap cleanup EXIT
trap 'exit 1' INT TERM HUP

# Without job control the background child is no process group leader, so setsid
# makes it the leader of a new group in place (no fork): $! is Chromium itself and
# its group holds exactly the processes it starts.
set +m
setsid "$chromium" --headless=new --no-sandbox --disable-gpu --remote-debugging-port=0 \
	--user-data-dir="$profile" --no-first-run --no-default-browser-check \
	--disable-background-networking --disable-component-update --disable-sync \
	--disable-extensions --disable-breakpad --disable-crash-reporter --metrics-recording-only --password-store=basic \
	--use-mock-keychain about:blank >"$profile.log" 2>&1 &
pid=$!
i=0
while [ ! -s "$profile/DevToolsActivePort" ]; do
	if ! kill -0 "$pid" 2>/dev/null || [ $i -ge 300 ]; then
		echo "chromium did not open its DevTools port; its output:" >&2
		cat "$profile.log" >&2
		rm -f "$profile.log"
		exit 1
	fi
	sleep 0.1
	i=$((i + 1))
done
rm -f "$profile.log"
"$python" "$here/report_browser.py" "$profile/DevToolsActivePort" "$report" "$shot" "$max_height"
