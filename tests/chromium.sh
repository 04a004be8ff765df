# Sourced by the browser tests (tests/pipeline/report_browser.sh,
# tests/console/test_console_browser.sh): find Chromium and a Python with the
# websocket module, start headless Chromium with a private profile and wait for its
# DevTools port. After chromium_start, $devtools holds the DevToolsActivePort file;
# the EXIT trap stops that Chromium (its own process group, by its id) and removes the
# profile. Exits 77 when chromium or python3-websocket is missing.
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
profile=$(mktemp -d "${TMPDIR:-/tmp}/kg_chromium_XXXXXX") || exit 1
pid=
chromium_cleanup() {
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
trap chromium_cleanup EXIT
trap 'exit 1' INT TERM HUP

chromium_start() {
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
	devtools=$profile/DevToolsActivePort
}
