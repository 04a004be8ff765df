#!/bin/sh
# A run killed (SIGKILL) at each rename of its commit, placed there by strace's syscall
# injection: the journal rename, each object folder moved aside and moved in, and each
# of OUTDIR's files. Whatever the moment, a reader never takes a half-made OUTDIR:
# `kogei report OUTDIR` first completes the commit (saying so) or keeps the earlier
# results, then every object process.json names is there, made with the cube format
# process.json records (the run before wrote f32 cubes, the killed one f16), and
# report.html is of that process.json; the console serves the settled folder (the
# first object moved aside). Needs strace.
# usage: test_process_commit_kill.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
FIX=$2/fixtures
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${3:-1}" json
command -v strace >/dev/null || kg_skip "strace missing (Debian package strace)"
kg_temp

# OUTDIR whole: every object of process.json with the recorded cube format, the report
# of this process.json, no journal or staging left.
whole() { # OUTDIR
	"$PY" - "$1" <<'PY'
import json, os, re, sys
o = sys.argv[1]
pj = json.load(open(o + "/process.json"))
want = {"f32": "4", "f16": "12"}[pj["parameters"]["cube"]]
for ob in pj["objects"]:
    h = open(os.path.join(o, ob["cube"])).read()
    got = re.search(r"data type\s*=\s*(\d+)", h).group(1)
    assert got == want, "%s: cube data type %s, process.json says %s" % (ob["capture"], got, pj["parameters"]["cube"])
rep = open(o + "/report.html").read()
assert pj["created"] in rep, "report.html is not of this process.json"
left = [e for e in os.listdir(o) if e.startswith(".kogei-")]
assert not left, "left in OUTDIR: %s" % left
print(pj["parameters"]["cube"])
PY
}

sim_scenes "$T" || { echo "FAIL: simulated scenes"; exit 1; }
S=$T/S
sim_acquire "$S" chart "$T/chart.tif" 10000 '' --layout cie-tcs-frame 2>>"$T/acquire.log" || fail=1
for n in 1 2; do
	sim_acquire "$S" object "$T/object.tif" 10000 "&seed=$n" --name object-$n 2>>"$T/acquire.log" || fail=1
done
sim_measure "$T/chart.cgats" || { echo "FAIL: kogei measure"; fail=1; }
[ $fail = 0 ] || exit 1
P="$S --spectra $T/chart.cgats --no-render --quiet --threads 1"
B=$T/base
run_or_exit "$KOGEI" process $P -o "$B"

# The renames of a whole f16 run over the f32 results, as strace counts them (all on
# the main thread): the commit's begin at the journal's.
cp -a "$B" "$T/probe"
# LeakSanitizer stops the world with ptrace at exit, which a traced process cannot
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0"
strace -f -qq -o "$T/renames" -e trace=rename -e signal=none "$KOGEI" process $P --cube f16 \
	-o "$T/probe" >/dev/null 2>&1 || { echo "FAIL: the traced run"; exit 1; }
main=$(awk 'NR == 1 {print $1}' "$T/renames")
awk -v m="$main" '$1 == m && $2 ~ /^rename\(/ {print ++n ": " $0}' "$T/renames" >"$T/main"
J=$(grep -m1 'kogei-commit' "$T/main" | cut -d: -f1)
N=$(wc -l <"$T/main")
[ -n "$J" ] && [ "$N" -gt "$J" ] || { echo "FAIL: no commit among the renames"; cat "$T/renames"; exit 1; }
echo "the commit: renames $J..$N of the main thread"

completed=0 kept=0
# the journal rename, the first object moved aside and in, the second moved aside and
# in, the first of OUTDIR's files, process.json and report.html
for k in $J $((J + 1)) $((J + 2)) $((J + 3)) $((J + 4)) $((J + 5)) $((N - 1)) $N; do
	O=$T/o$k
	cp -a "$B" "$O"
	strace -f -qq -o /dev/null -e trace=rename -e inject=rename:signal=KILL:when=$k \
		"$KOGEI" process $P --cube f16 -o "$O" >"$T/out" 2>"$T/err"
	what=$(sed -n "${k}p" "$T/main" | sed 's/^[0-9]*: [0-9]* *//')
	ls -d "$O"/.kogei-commit.* "$O"/.kogei-run.* 2>/dev/null | grep -q . ||
		{ echo "FAIL: rename $k ($what): the run was not stopped inside its commit"; fail=1; }
	if [ $k = $((J + 1)) ]; then
		# object-1 moved aside, the new one not yet in: the console serves the folder
		# settled (a reader with no run live completes the commit first)
		"$PY" - "$KOGEI" "$S" "$O" "$2/tests/console" <<'PY' || fail=1
import sys
sys.path.insert(0, sys.argv[4])
from console_common import Console
kogei, session, out = sys.argv[1:4]
c = Console(kogei, session, [], extra=["--out", out])
try:
    st, body = c.request("GET", "/out/process.json")
    import json
    pj = json.loads(body) if st == 200 else {}
    bad = [o["cube"] for o in pj.get("objects", [])
           if c.request("GET", "/out/" + o["cube"])[0] != 200]
    ok = st == 200 and pj["parameters"]["cube"] == "f16" and not bad
    print("console: process.json %d (%s cubes), missing %s" % (st, pj.get("parameters", {}).get("cube"), bad))
finally:
    c.stop()
sys.exit(0 if ok else 1)
PY
	fi
	expect_exit 0 "$KOGEI" report "$O"
	got=$(whole "$O" 2>"$T/whole") || { echo "FAIL: rename $k ($what): kogei report left OUTDIR half-made:"; cat "$T/whole" "$T/err"; fail=1; }
	case $got in f16) completed=$((completed + 1)) ;; f32) kept=$((kept + 1)) ;; esac
	if ls -d "$O"/.kogei-commit.* >/dev/null 2>&1; then
		echo "FAIL: rename $k: a journal left after kogei report"; fail=1
	fi
	echo "killed at rename $k ($what): kogei report found it $got"
done
check "a kill after the journal rename is completed by the reader" test $completed -ge 1
check "a kill at the journal rename keeps the earlier results" test $kept -ge 1
[ $fail = 0 ] && echo "ok: $completed completed, $kept kept"
exit $fail
