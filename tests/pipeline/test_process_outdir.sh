#!/bin/sh
# kogei process and its OUTDIR (issue 33, items 1 and 2) on a small session recorded
# with the sim devices (a chart, four objects): an OUTDIR inside the session, a
# foreign non-empty folder, another session's output, a folder at an object's name
# that process.json does not list, an input inside a folder a run replaces: each
# refused, naming it, with nothing written and nothing changed. Then interrupted runs:
# SIGKILL mid-run (OUTDIR keeps the previous results; the next run removes the
# leftovers, old kogei's .NAME.partial-PID / .NAME.old-PID too), a run killed half-way
# through putting its results in place (completed by the next run), SIGINT and SIGTERM
# (a message, exit 130 / 143, the f32 results kept whole while a --cube f16 re-run was
# staged: process.json, report.html and cube.hdr agree) and SIGINT on a first run (the
# OUTDIR it created removed).
# usage: test_process_outdir.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
FIX=$2/fixtures
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${3:-1}" json
env --default-signal=INT true 2>/dev/null || kg_skip "env --default-signal (coreutils 8.31) missing"
kg_temp
# Every entry under a folder (but its own dot entries) with its inode, size and
# modification time: a file rewritten, replaced or removed changes the listing.
tree_sum() {
	(cd "$1" && find . -mindepth 1 -path './.*' -prune -o -printf '%p %i %s %T@\n' | LC_ALL=C sort)
}
same_tree() { tree_sum "$1" >"$T/after"; cmp -s "$2" "$T/after"; }
no_leftovers() { # OUTDIR: no dot entry
	[ -z "$(ls -A "$1" | grep '^\.')" ] || { echo "left in $1:"; ls -A "$1" | grep '^\.'; return 1; }
}
# The cube's ENVI data type against what process.json and report.html say.
consistent() { # OUTDIR
	"$PY" - "$1" <<'PY'
import json, os, re, sys
o = sys.argv[1]
pj = json.load(open(o + "/process.json"))
fmt = pj["parameters"]["cube"]
want = {"f32": "4", "f16": "12"}[fmt]
for ob in pj["objects"]:
    h = open(os.path.join(o, ob["cube"])).read()
    got = re.search(r"data type\s*=\s*(\d+)", h).group(1)
    assert got == want, (ob["capture"], fmt, got)
rep = open(o + "/report.html").read()
assert pj["created"] in rep, "report.html is not of this process.json"
PY
}
# Start kogei process in the background with the signals' default actions; wait until
# its staging folder holds the object named, then send the signal.
interrupt() { # signal object outdir args...
	sig=$1 obj=$2 out=$3; shift 3
	env --default-signal=INT,TERM,HUP "$KOGEI" process "$@" -o "$out" >"$T/out" 2>"$T/err" &
	pid=$!
	i=0
	while [ $i -lt 3000 ] && ! ls -d "$out"/.kogei-run.*/"$obj" >/dev/null 2>&1; do
		kill -0 $pid 2>/dev/null || break
		sleep 0.01; i=$((i + 1))
	done
	ls -d "$out"/.kogei-run.*/"$obj" >/dev/null 2>&1 ||
		{ echo "FAIL: the run never staged $obj"; cat "$T/err"; fail=1; }
	kill -"$sig" $pid
	wait $pid
	rc=$?
}

sim_scenes "$T" || { echo "FAIL: simulated scenes"; exit 1; }
S=$T/S
sim_acquire "$S" chart "$T/chart.tif" 10000 '' --layout cie-tcs-frame 2>>"$T/acquire.log" || fail=1
for n in 1 2 3 4; do
	sim_acquire "$S" object "$T/object.tif" 10000 "&seed=$n" --name object-$n 2>>"$T/acquire.log" || fail=1
done
sim_measure "$T/chart.cgats" || { echo "FAIL: kogei measure"; fail=1; }
[ $fail = 0 ] || exit 1
P="$S --spectra $T/chart.cgats --no-render --quiet --threads 1"
O=$T/res
expect_exit 0 "$KOGEI" process $P -o "$O"
tree_sum "$S" >"$T/session.sum"
tree_sum "$O" >"$T/out.sum"
# The same session moved to another disk with its results (cp -a, the original gone):
# re-processed in place, nothing to redo.
mkdir "$T/nas" && cp -a "$S" "$T/nas/S" && cp -a "$O" "$T/nas/res"
expect_exit 0 "$KOGEI" process "$T/nas/S" --spectra "$T/chart.cgats" --no-render --threads 1 \
	-o "$T/nas/res"
check "a moved session re-processed into its moved results" grep -q "0 processed, 4 unchanged" "$T/out"
rm -rf "$T/nas"

# ---- item 1: OUTDIR refusals, before anything is written ------------------------------
# Inside the session: its captures, its frames, a new folder in it.
for d in captures frames captures/object-1 new; do
	expect_exit 1 "$KOGEI" process $P -o "$S/$d"
	check "-o S/$d: refused as inside the session" grep -q "inside the session" "$T/err"
done
check "the session's files intact" same_tree "$S" "$T/session.sum"
check "-o S/new: not created" test ! -e "$S/new"
# A foreign non-empty folder: an unrelated .dng, or kogei-looking files without process.json.
F=$T/foreign
mkdir -p "$F/object-1" && echo raw >"$F/IMG_0001.dng" && echo x >"$F/object-1/notes.txt" &&
	echo '{}' >"$F/camera.json" && echo '<p>mine</p>' >"$F/report.html"
tree_sum "$F" >"$T/f.sum"
expect_exit 1 "$KOGEI" process $P -o "$F"
check "foreign folder refused, naming what is there" grep -q "holds no process.json" "$T/err"
check "foreign folder: its file named" grep -q "IMG_0001.dng" "$T/err"
check "foreign folder unchanged" same_tree "$F" "$T/f.sum"
# Another session's output (another recording: a session of its own id).
cp -r "$S" "$T/S2"
"$PY" - "$T/S2/session.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
d["id"] = "00000000-0000-4000-8000-000000000001"
json.dump(d, open(sys.argv[1], "w"))
PY
cp -r "$O" "$T/other"
tree_sum "$T/other" >"$T/o.sum"
expect_exit 1 "$KOGEI" process "$T/S2" --spectra "$T/chart.cgats" --no-render -o "$T/other"
check "another session's output refused" grep -q "holds the results of another session" "$T/err"
check "another session's output: what differs said" grep -q "session id .* there, 00000000-0000-4000-8000-000000000001 here" "$T/err"
check "another session's output unchanged" same_tree "$T/other" "$T/o.sum"
# A folder at an object's name that process.json does not list.
cp -r "$O" "$T/unlisted"
"$PY" - "$T/unlisted/process.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
d["objects"] = [o for o in d["objects"] if o["capture"] != "object-2"]
json.dump(d, open(sys.argv[1], "w"))
PY
tree_sum "$T/unlisted" >"$T/u.sum"
expect_exit 1 "$KOGEI" process $P -o "$T/unlisted" --angle 40
check "unlisted object folder refused, named" grep -q "unlisted/object-2: exists" "$T/err"
check "unlisted: nothing changed" same_tree "$T/unlisted" "$T/u.sum"
# An input inside a folder the run would replace: --mask in an object's folder.
W=$(sed -n 's/^samples *= *//p' "$O/object-1/labels.hdr")
H=$(sed -n 's/^lines *= *//p' "$O/object-1/labels.hdr")
"$PY" - "$O/object-1/mask.png" "$W" "$H" <<'PY'
import struct, sys, zlib
p, w, h = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
raw = b"".join(b"\0" + b"\xff" * w for _ in range(h))
def chunk(t, x):
    return struct.pack(">I", len(x)) + t + x + struct.pack(">I", zlib.crc32(t + x))
open(p, "wb").write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
                   + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
PY
tree_sum "$O" >"$T/out.sum"
expect_exit 1 "$KOGEI" process $P -o "$O" --mask "$O/object-1/mask.png"
check "--mask inside an object folder refused" grep -q "mask.png: is inside" "$T/err"
check "--mask refusal: OUTDIR unchanged, the mask kept" same_tree "$O" "$T/out.sum"
rm -f "$O/object-1/mask.png"
# --reference given as a file the run rewrites (a lab session writes reference.json).
cp "$O/reference.json" "$T/ref.json"
expect_exit 1 "$KOGEI" process $P -o "$O" --layout "$O/camera.json"
check "an input that is OUTDIR's own file refused" grep -q "which this run writes" "$T/err"
# A refused first run leaves no folder behind.
expect_exit 1 "$KOGEI" process "$S" --reference "$T/missing.json" --no-render -o "$T/new/deep"
check "a failed first run removes the OUTDIR it created" test ! -e "$T/new"
tree_sum "$O" >"$T/out.sum"

# ---- item 2: interrupted runs ---------------------------------------------------------
# SIGKILL mid-run: the previous results stay whole; the next run clears the leftovers.
interrupt KILL object-2 "$O" $P --angle 40
check "SIGKILL: OUTDIR's results as they were" same_tree "$O" "$T/out.sum"
check "SIGKILL: process.json, report and cube.hdr agree" consistent "$O"
ls -A "$O" | grep -q '^\.kogei-run\.' || { echo "FAIL: SIGKILL left no staging folder to recover (test not exercised)"; fail=1; }
mkdir -p "$O/.object-1.partial-99999" "$O/.object-3.old-99999"
echo x >"$O/.object-1.partial-99999/cube.img"
expect_exit 0 "$KOGEI" process $P -o "$O"
check "after SIGKILL: unchanged objects kept" grep -q "0 processed, 4 unchanged" "$T/out"
check "after SIGKILL: the next run left no dot entries" no_leftovers "$O"
# A run killed half-way through its swap: the journal is completed by the next run.
J=$O/.kogei-commit.99999
mkdir "$J" && cp -r "$O/object-3" "$J/object-3" && echo journal >"$J/object-3/marker"
cp "$O/process.json" "$J/process.json"
mkdir "$O/.kogei-old.99999" && mv "$O/object-3" "$O/.kogei-old.99999/"
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" --no-render --threads 1 -o "$O"
check "journal completed: the staged folder in place" test -s "$O/object-3/marker"
check "journal completed: said so" grep -q "completed the results of a run" "$T/err"
check "journal completed: no dot entries" no_leftovers "$O"
check "journal completed: consistent" consistent "$O"
rm -f "$O/object-3/marker"
# SIGINT during a --cube f16 re-run: a message, exit 130, the f32 results kept whole.
tree_sum "$O" >"$T/out.sum"
interrupt INT object-2 "$O" $P --cube f16
check "SIGINT: exit 130 (got $rc)" test "$rc" = 130
check "SIGINT: says what OUTDIR keeps" grep -q "interrupted by SIGINT: .* keeps the results of its previous run" "$T/err"
check "SIGINT: OUTDIR exactly as before" same_tree "$O" "$T/out.sum"
check "SIGINT: no dot entries" no_leftovers "$O"
check "SIGINT: process.json, report and cube.hdr agree" consistent "$O"
interrupt TERM object-3 "$O" $P --cube f16
check "SIGTERM: exit 143 (got $rc)" test "$rc" = 143
check "SIGTERM: OUTDIR exactly as before" same_tree "$O" "$T/out.sum"
check "SIGTERM: no dot entries" no_leftovers "$O"
# The re-run that completes: f16 throughout.
expect_exit 0 "$KOGEI" process $P --cube f16 -o "$O"
check "f16 re-run: all processed" grep -q "4 processed, 0 unchanged" "$T/out"
check "f16 re-run: process.json, report and cube.hdr agree" consistent "$O"
check "f16 re-run: no dot entries" no_leftovers "$O"
# SIGINT on a first run: nothing left, the folder it created removed.
interrupt INT object-1 "$T/first" $P
check "first run SIGINT: exit 130 (got $rc)" test "$rc" = 130
check "first run SIGINT: message" grep -q "interrupted by SIGINT: nothing was written" "$T/err"
check "first run SIGINT: OUTDIR removed" test ! -e "$T/first"

exit $fail
