#!/bin/sh
# preview_rate.sh KOGEI [WIDTH HEIGHT SECONDS]: the console's preview rate and latency
# on a sim camera (default 4000x3000, 12 Mpix) in headless Chromium (docs/console.md).
set -u
kogei=$1 w=${2:-4000} h=${3:-3000} s=${4:-15}
here=$(cd "$(dirname "$0")" && pwd)
. "$here/../chromium.sh"
work=$(mktemp -d "${TMPDIR:-/tmp}/kg_console_rate_XXXXXX") || exit 1
trap 'chromium_cleanup; rm -rf "$work"' EXIT
chromium_start
KOGEI_CAMERA_DISCOVERY=none "$python" "$here/preview_rate.py" "$kogei" "$devtools" "$work" "$w" "$h" "$s"
