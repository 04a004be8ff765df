#!/bin/sh
# test_report_browser.sh MAKE_FIXTURE KOGEI REPORT_BROWSER_SH
# The synthetic OUTDIR (make_report_fixture), its page written by `kogei report`,
# checked in headless Chromium by report_browser.sh. The screenshot is kept as
# $KOGEI_BUILD_ROOT/tests/pipeline/report-browser.png for a person to look at.
set -u
make_fixture=$1 kogei=$2 check=$3
tmp=$(mktemp -d "${TMPDIR:-/tmp}/kg_report_browser_XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT
"$make_fixture" "$tmp/out" || exit 1
"$kogei" report "$tmp/out" >/dev/null || { echo "kogei report failed" >&2; exit 1; }
sh "$check" "$tmp/out/report.html" "$tmp/shot.png"
status=$?
if [ $status -ne 77 ] && [ -f "$tmp/shot.png" ] && [ -n "${KOGEI_BUILD_ROOT:-}" ]; then
	cp "$tmp/shot.png" "$KOGEI_BUILD_ROOT/tests/pipeline/report-browser.png"
fi
exit $status
