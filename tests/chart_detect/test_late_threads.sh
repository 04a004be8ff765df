#!/bin/sh
# kogei chart detect with 2 threads while every thread starts late, inside a realloc
# of its creator that moves the block (late_threads_preload.c): the patches are those
# of a run without the shim, and the shim did start threads late. libapriltag 3.3's
# workers crashed here (a task called through its freed array), as they once did in
# CI: the tags are found on one thread with that library.
# usage: test_late_threads.sh KOGEI SHIM SOURCE_ROOT
set -u
KOGEI=$1 SHIM=$2 ROOT=$3
LAYOUT=$ROOT/fixtures/charts/colorchecker24-frame.json
[ -r "$LAYOUT" ] || { echo "SKIP: $LAYOUT is missing"; exit 77; }
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail=0
"$KOGEI" chart print --layout "$LAYOUT" -o "$T/frame.png" || { echo "FAIL: chart print"; exit 1; }
"$KOGEI" chart detect --layout "$LAYOUT" "$T/frame.png" -o "$T/plain.cgats" --threads 2 \
	--quiet || { echo "FAIL: chart detect without the shim"; exit 1; }
for i in 1 2 3; do
	rm -f "$T/late.log"
	# the shim comes before the sanitizer runtime in the ASan build
	KOGEI_LATE_THREADS_LOG=$T/late.log ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0 \
		LD_PRELOAD=$SHIM "$KOGEI" chart detect --layout "$LAYOUT" "$T/frame.png" \
		-o "$T/late.cgats" --threads 2 --quiet 2>"$T/err"
	rc=$?
	if [ $rc != 0 ]; then
		echo "FAIL: run $i with threads started late exited $rc"; tail -20 "$T/err"; fail=1
		break
	fi
	read -r _ late _ caught <"$T/late.log" || { echo "FAIL: no shim log"; fail=1; break; }
	echo "run $i: $late thread(s) started late, $caught took from a block before it moved"
	[ "$late" -ge 1 ] || { echo "FAIL: the shim started no thread late"; fail=1; }
	# same patches: the detector's results do not depend on thread timing
	grep -v '^CREATED\|^ORIGINATOR\|^DESCRIPTOR' "$T/plain.cgats" >"$T/a"
	grep -v '^CREATED\|^ORIGINATOR\|^DESCRIPTOR' "$T/late.cgats" >"$T/b"
	cmp -s "$T/a" "$T/b" || { echo "FAIL: run $i: patches differ from the run without the shim"; diff "$T/a" "$T/b" | head; fail=1; }
done
[ $fail = 0 ] && echo "ok"
exit $fail
