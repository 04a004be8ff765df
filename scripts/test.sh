#!/bin/sh
# Install what is missing, build, and run the whole test suite. Idempotent.
# Usage: scripts/test.sh [BUILD_DIR [meson setup options...]]
# Ends with one line: "N passed, N failed, N skipped"; exits non-zero on any failure.
set -eu
cd "$(dirname "$0")/.."
./scripts/setup.sh
BUILD=${1:-build}
[ $# -gt 0 ] && shift
if [ -f "$BUILD/build.ninja" ]; then
	meson setup --reconfigure "$BUILD" "$@" >/dev/null
else
	meson setup "$BUILD" "$@"
fi
ninja -C "$BUILD"
set +e
meson test -C "$BUILD" --num-processes "${KOGEI_TEST_JOBS:-2}" --print-errorlogs
status=$?
set -e
python3 - "$BUILD/meson-logs/testlog.json" <<'PY'
import json, sys
passed = failed = skipped = 0
with open(sys.argv[1]) as f:
    for line in f:
        r = json.loads(line).get("result")
        if r in ("OK", "EXPECTEDFAIL"):
            passed += 1
        elif r == "SKIP":
            skipped += 1
        else:
            failed += 1
print(f"{passed} passed, {failed} failed, {skipped} skipped")
PY
exit $status
