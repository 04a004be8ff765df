#!/bin/sh
# Make the images of docs/ from real runs of the current build, so that no picture in
# the documentation shows anything the code did not do:
#   docs/report.png       the top of the demo's report.html, as headless Chromium shows it
#   docs/console-*.png    the operator's console on a sim session (the browser test's views)
# and any further image script of the tree (scripts/docs_*.sh) when present.
# Usage: scripts/docs_images.sh [BUILD_DIR]   (default build; needs chromium and
# python3-websocket, which scripts/setup.sh installs)
set -eu
cd "$(dirname "$0")/.."
SRC=$(pwd)
BUILD=${1:-build}
KOGEI=$(realpath "$BUILD/cli/kogei")
[ -x "$KOGEI" ] || { echo "docs_images: $BUILD/cli/kogei not built (run ninja -C $BUILD)" >&2; exit 1; }
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
export KOGEI_SOURCE_ROOT="$SRC" KOGEI_BUILD_ROOT="$(realpath "$BUILD")"

echo "docs_images: kogei demo (a few minutes)"
"$KOGEI" demo -o "$T/demo" > "$T/demo.log" 2>&1 || { tail -20 "$T/demo.log"; exit 1; }
echo "docs_images: docs/report.png"
sh tests/pipeline/report_browser.sh "$T/demo/site/report.html" "$T/report.png" 1400
mv "$T/report.png" docs/report.png

echo "docs_images: docs/console-*.png"
sh tests/console/test_console_browser.sh "$KOGEI" "$T/console"
for f in console-live console-chart console-capture console-session; do
	mv "$T/console/$f.png" "docs/$f.png"
done

for s in scripts/docs_*.sh; do
	[ "$s" = scripts/docs_images.sh ] && continue
	[ -f "$s" ] || continue
	echo "docs_images: $s"
	sh "$s" "$BUILD"
done
echo "docs_images: done (git status docs/ shows what changed)"
