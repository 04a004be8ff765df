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
here=$(cd "$(dirname "$0")" && pwd)
. "$here/../chromium.sh"
chromium_start
"$python" "$here/report_browser.py" "$devtools" "$report" "$shot" "$max_height"
