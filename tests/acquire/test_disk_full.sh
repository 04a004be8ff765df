#!/bin/sh
# `kogei acquire` on a full disk: a 1 MiB tmpfs mounted in a private mount namespace
# (unshare -m; skipped, exit 77, where that is not allowed). A capture whose raw frames
# or whose outputs do not fit exits 1 (not 3: the camera did not fail) with a message
# naming ENOSPC, and leaves session.json, frames/index.jsonl and frames/camera.json
# byte-identical, with no frames/ or captures/ folder of the failed capture.
set -u
kogei=$1
command -v unshare >/dev/null 2>&1 || { echo "SKIP: unshare not installed"; exit 77; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir "$tmp/mnt"
if ! unshare -m sh -c "mount -t tmpfs -o size=1m tmpfs '$tmp/mnt'" 2>/dev/null; then
	echo "SKIP: cannot mount a tmpfs in a private mount namespace (needs root)"
	exit 77
fi
cat >"$tmp/run.sh" <<'INNER'
set -u
kogei=$1 mnt=$2 log=$3
fail=0
check() { if ! eval "$2"; then echo "FAIL: $1"; fail=1; fi; }
mount -t tmpfs -o size=1m tmpfs "$mnt" || exit 99
s="$mnt/session"
"$kogei" acquire --camera 'sim:?width=32&height=24' --out "$s" --kind object --frames 2 \
	>/dev/null 2>"$log" || { echo "FAIL: first capture"; cat "$log"; exit 1; }
keep=$(dirname "$log")  # outside the small disk
for f in session.json frames/index.jsonl frames/camera.json; do
	cp "$s/$f" "$keep/before.$(echo "$f" | tr / _)"
done
same() {
	for f in session.json frames/index.jsonl frames/camera.json; do
		cmp -s "$s/$f" "$keep/before.$(echo "$f" | tr / _)" || { echo "$f changed"; return 1; }
	done
}
# 1: the raw frames do not fit (512 KiB each).
"$kogei" acquire --camera 'sim:?width=512&height=512' --out "$s" --kind object \
	--frames 4 >/dev/null 2>"$log"
rc=$?
cat "$log"
check "frames: exit 1 (got $rc)" '[ $rc -eq 1 ]'
check "frames: ENOSPC named" 'grep -q "ENOSPC" "$log"'
check "frames: not blamed on the camera" '! grep -q "completed, .* dropped" "$log"'
check "frames: session as it was" 'same'
check "frames: no frames of the failed capture" '[ ! -e "$s/frames/object-0002" ]'
check "frames: no outputs of the failed capture" '[ ! -e "$s/captures/object-0002" ]'
# 2: the frames are not recorded, the outputs (float32 TIFF, 1 MiB each) do not fit.
"$kogei" acquire --camera 'sim:?width=512&height=512' --out "$s" --kind object \
	--frames 1 --no-record >/dev/null 2>"$log"
rc=$?
cat "$log"
check "outputs: exit 1 (got $rc)" '[ $rc -eq 1 ]'
check "outputs: ENOSPC named" 'grep -q "ENOSPC" "$log"'
check "outputs: session as it was" 'same'
check "outputs: no outputs of the failed capture" '[ ! -e "$s/captures/object-0002" ]'
exit $fail
INNER
unshare -m sh "$tmp/run.sh" "$kogei" "$tmp/mnt" "$tmp/log"
rc=$?
[ $rc -eq 0 ] && echo "disk-full: ok"
exit $rc
