#!/bin/sh
# A collection's index.html in headless Chromium (collection_browser.py): two small sim
# sessions and one broken on purpose, run by kogei collection run; the table's rows
# against collection.json, record text shown as written, thumbnails decoded, sorting
# by a click on a column's name, no request leaving the file and no console error.
# usage: test_collection_browser.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
ROOT=$2
kg_need "${3:-1}" "built without libapriltag or OpenCV (chart tags, demosaicing)"
kg_need_tcs
here=$(cd "$(dirname "$0")" && pwd)
case $KOGEI in /*) ;; *) KOGEI=$(pwd)/$KOGEI ;; esac
case $ROOT in /*) ;; *) ROOT=$(pwd)/$ROOT ;; esac
FIX=$ROOT/fixtures
. "$here/collection_sessions.sh"
. "$here/../chromium.sh"
T=$(mktemp -d) || exit 1
trap 'chromium_cleanup; [ -n "${KEEP:-}" ] || rm -rf "$T"' EXIT
C=$T/col
coll_sessions "$C" 2 && coll_broken "$C" broken || { echo "FAIL: setting up the sessions"; exit 1; }
# accessions out of the list's order, one with HTML-special characters, one quoted
# (a comma and a quote inside)
cat >"$C/list.csv" <<'LIST'
session,spectra,meta.accession
s1,chart.cgats,"Z-9, lot ""b"""
s2,chart.cgats,A-1<i>x</i>&amp;
broken,chart.cgats,M-5
LIST
"$KOGEI" collection run "$C/list.csv" -o "$T/res" >"$T/run.out" 2>"$T/run.err"
rc=$?
[ $rc = 1 ] || { echo "FAIL: kogei collection run exited $rc, expected 1 (one failed)"; cat "$T/run.err"; exit 1; }
chromium_start
"$python" "$here/collection_browser.py" "$devtools" "$T/res/index.html" "$T/res/collection.json"
