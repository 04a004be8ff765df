#!/bin/sh
# kogei collection run with the local engine on small sim sessions: a list of four
# (one without a chart, broken on purpose) run by 2 workers; the record
# (collection.json: status, reason naming the file, job, time, objects with accession,
# warnings and held-out dE00); cube.img and labels.img byte-identical to a direct
# `kogei process`; resume (only the failed entry runs again, done entries keep their
# job; the fixed one runs; a changed option runs that entry only); status; bad lists
# refused before anything runs, each problem named by line and column; a SIGTERM to
# the runner leaves every entry done or as it was; the Slurm engine's script and sbatch
# calls (a stand-in sbatch and squeue on the PATH).
# usage: test_collection.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
ROOT=$2
kg_need "${3:-1}" "built without libapriltag or OpenCV (chart tags, demosaicing)"
kg_need_tcs
kg_python json
case $KOGEI in /*) ;; *) KOGEI=$(pwd)/$KOGEI ;; esac
case $ROOT in /*) ;; *) ROOT=$(pwd)/$ROOT ;; esac
FIX=$ROOT/fixtures
. "$(dirname "$0")/collection_sessions.sh"
kg_temp
cd "$T" || exit 1
C=$T/col
coll_sessions "$C" 3 && coll_broken "$C" broken ||
	{ echo "FAIL: setting up the sessions"; exit 1; }
cat >"$C/list.csv" <<'EOF'
session,spectra,name,meta.accession,meta.title
s1,chart.cgats,,A-1,First <b>&
s2,chart.cgats,second,A-2,Second
s3,chart.cgats,,A-3,Third
broken,chart.cgats,,A-4,Broken on purpose
EOF

# ---- the first run: one failure, the others done ------------------------------------
expect_exit 1 "$KOGEI" collection run "$C/list.csv" -o res --jobs 2
check "the failed entry named on stderr with its line and reason" \
	grep -q "broken (.*list.csv line 5): failed: .*broken/session.json: no chart capture" "$T/err"
check "the summary line counts 3 done, 1 failed" grep -q "4 entries: 3 done, 1 failed" "$T/out"
"$PY" - res <<'PYEOF' || fail=1
import json, os, sys
out = sys.argv[1]
r = json.load(open(os.path.join(out, "collection.json")))
bad = []
def want(cond, msg):
    if not cond:
        bad.append(msg)
want(r["format"] == "kogei-collection/1", "format")
want(r["engine"] == "local", "engine %r" % r["engine"])
want(r["counts"] == {"entries": 4, "done": 3, "failed": 1, "pending": 0}, "counts %r" % r["counts"])
by = {e["name"]: e for e in r["entries"]}
want(sorted(by) == ["broken", "s1", "s3", "second"], "names %r" % sorted(by))
for n, acc, given in (("s1", "A-1", "s1"), ("second", "A-2", "s2"), ("s3", "A-3", "s3")):
    e = by[n]
    want(e["status"] == "done" and e["reason"] is None, "%s: status %r" % (n, e["status"]))
    want(e["session"]["given"] == given and os.path.isabs(e["session"]["path"]) and
         os.path.isfile(os.path.join(e["session"]["path"], "session.json")), "%s: session %r" % (n, e["session"]))
    want(e["job"].startswith("local:") and "worker-" in e["job"], "%s: job %r" % (n, e["job"]))
    want(e["time"]["seconds"] > 0 and e["time"]["finished"] >= e["time"]["started"], "%s: time" % n)
    want(os.path.isfile(os.path.join(out, n, "process.json")), "%s: no process.json" % n)
    want(len(e["objects"]) == 1, "%s: objects %r" % (n, e["objects"]))
    o = e["objects"][0]
    pj = json.load(open(os.path.join(out, n, "process.json")))
    want(o["name"] == pj["objects"][0]["capture"], "%s: object name" % n)
    want(o["accession"] == acc, "%s: accession %r" % (n, o["accession"]))
    want(o["warnings"] == pj["objects"][0]["warnings"], "%s: warnings differ from process.json" % n)
    # held-out dE00 recomputed from process.json's patches
    v = sorted(p["de00_d50_heldout"] for p in pj["calibration"]["patches"]
               if isinstance(p.get("de00_d50_heldout"), (int, float)))
    de = o["de00_heldout"]
    want(de and de["n"] == len(v) and abs(de["mean"] - sum(v) / len(v)) < 1e-9 and
         de["max"] == v[-1], "%s: de00_heldout %r" % (n, de))
    want(o["grade"] and o["grade"]["iso19264_1"] in "ABC none", "%s: grade %r" % (n, o["grade"]))
    want(os.path.isfile(os.path.join(out, ".collection", "thumbs", n, o["name"] + ".png")), "%s: thumbnail" % n)
b = by["broken"]
want(b["status"] == "failed", "broken: status %r" % b["status"])
want(b["reason"] and "broken/session.json" in b["reason"] and "no chart capture" in b["reason"],
     "broken: reason %r" % b["reason"])
want(b["objects"] == [] and b["job"].startswith("local:"), "broken: objects/job")
want(not os.path.exists(os.path.join(out, "broken", "process.json")), "broken: has results")
for m in bad:
    print("FAIL: collection.json: " + m)
sys.exit(1 if bad else 0)
PYEOF

# ---- the same as a direct kogei process: byte-identical cube and labels ---------------
run "$KOGEI" process "$C/s3" --spectra "$C/chart.cgats" -o direct --meta accession=A-3 \
	--meta title=Third --quiet
obj=$(cd direct && ls -d object-*/ | head -1)
for f in cube.img labels.img; do
	check "$obj$f byte-identical to a direct kogei process" cmp -s "direct/$obj$f" "res/s3/$obj$f"
done

# ---- status -------------------------------------------------------------------------------
expect_exit 1 "$KOGEI" collection status res
check "status counts" grep -q "4 entries: 3 done, 1 failed, 0 pending" "$T/out"
check "status names the failure" grep -q "broken .*no chart capture" "$T/out"
expect_exit 1 "$KOGEI" collection status "$T"
check "status of a folder that is no collection" grep -q "not a collection" "$T/err"

# ---- resume: only the failed entry runs again ------------------------------------------
jobs_before=$("$PY" -c 'import json,sys; r=json.load(open(sys.argv[1])); print(sorted((e["name"], e["job"], e["time"]["finished"]) for e in r["entries"] if e["status"]=="done"))' res/collection.json)
cp res/s1/process.json s1.before
sleep 1
expect_exit 1 "$KOGEI" collection run "$C/list.csv" -o res --jobs 2
check "a rerun runs only the failed entry" grep -q "3 done, 1 failed, 0 pending (1 run now)" "$T/out"
check "a done entry's results are untouched" cmp -s s1.before res/s1/process.json
jobs_after=$("$PY" -c 'import json,sys; r=json.load(open(sys.argv[1])); print(sorted((e["name"], e["job"], e["time"]["finished"]) for e in r["entries"] if e["status"]=="done"))' res/collection.json)
check "done entries keep their job and time" [ "$jobs_before" = "$jobs_after" ]

coll_fix "$C" broken || { echo "FAIL: adding the chart"; fail=1; }
run "$KOGEI" collection run "$C/list.csv" -o res --jobs 2
check "the fixed entry runs, alone" grep -q "4 entries: 4 done, 0 failed, 0 pending (1 run now)" "$T/out"
check "the fixed entry has its results" [ -f res/broken/process.json ]

# a changed option (cube) runs that entry only
sed 's/^s3,chart.cgats,,A-3,Third$/s3,chart.cgats,,A-3,Third again/' "$C/list.csv" >"$C/list2.csv"
run "$KOGEI" collection run "$C/list2.csv" -o res --jobs 2
check "a changed meta.* cell runs that entry only" grep -q "(1 run now)" "$T/out"
check "the changed title reaches the record" grep -q '"title": "Third again"' res/collection.json
run "$KOGEI" collection run "$C/list2.csv" -o res
check "nothing to run when nothing changed" grep -q "(0 run now)" "$T/out"
run "$KOGEI" collection status res

# ---- bad lists: refused before anything runs, each problem named ------------------------
refuse() { # DESC CSV-TEXT EXPECTED-LINE...
	desc=$1 text=$2
	shift 2
	printf '%s\n' "$text" >"$C/bad.csv"
	expect_exit 2 "$KOGEI" collection run "$C/bad.csv" -o badout
	for want in "$@"; do
		grep -qF -- "$want" "$T/err" || { echo "FAIL: $desc: no '$want' in:"; cat "$T/err"; fail=1; }
	done
	[ ! -e badout/.collection/plan.json ] && [ -z "$(ls badout 2>/dev/null | grep -v '^$')" ] ||
		{ echo "FAIL: $desc: something was written"; ls -la badout; fail=1; }
	rm -rf badout
}
refuse "unknown column" "session,spectra,colour
s1,chart.cgats,red" "bad.csv: line 1, column 3 (colour): unknown column"
refuse "missing session" "session,spectra
s1,chart.cgats
nowhere,chart.cgats" "bad.csv: line 3, column 1 (session): 'nowhere'"
refuse "duplicate name" "# a comment line
session,spectra,name
s1,chart.cgats,x
s2,chart.cgats,x" "bad.csv: line 4, column 3 (name): name 'x' is also the name of line 3"
refuse "unsafe name" "session,spectra,name
s1,chart.cgats,../up" "bad.csv: line 2, column 3 (name): name '../up' is not a safe folder name"
refuse "all problems at once" "session,spectra,name,cube
s1,chart.cgats,.hidden,f32
nowhere,chart.cgats,,f64
s2,missing.cgats,ok,f16" "line 2, column 3 (name)" "line 3, column 1 (session)" \
	"line 3, column 4 (cube): 'f64'" "line 4, column 2 (spectra): 'missing.cgats'" "4 problem(s)"
refuse "no spectra or reference" "session,name
s1,a" "line 1: no column 'spectra' or 'reference'"
expect_exit 2 "$KOGEI" collection run "$C/list.csv" -o x --jobs 0
expect_exit 2 "$KOGEI" collection run "$C/list.csv" -o x --partition p
expect_exit 2 "$KOGEI" collection run "$C/list.csv" -o x --engine cloud

# ---- interrupted: SIGTERM to the runner -----------------------------------------------
sed 's/,A-1,/,B-1,/; s/,A-3,/,B-3,/' "$C/list.csv" >"$C/list3.csv"
"$KOGEI" collection run "$C/list3.csv" -o res --jobs 2 >term.out 2>term.err &
runner=$!
i=0
while [ $i -lt 100 ] && ! ls res/*/.kogei-run.* >/dev/null 2>&1; do
	sleep 0.05
	i=$((i + 1))
done
kill -TERM $runner
wait $runner
rc=$?
check "the interrupted runner ends by SIGTERM (exit $rc)" [ "$rc" = 143 ]
"$PY" - res <<'PYEOF' || fail=1
import json, os, sys
out = sys.argv[1]
plan = json.load(open(os.path.join(out, ".collection", "plan.json")))
bad = 0
for e in plan["entries"]:
    p = os.path.join(out, ".collection", "entries", e["name"] + ".json")
    s = json.load(open(p))
    if s["key"] == e["key"] and s["status"] != "done":
        print("FAIL: %s: state %r after SIGTERM (expected done, or the earlier key)" % (e["name"], s["status"])); bad = 1
    if s["key"] == e["key"] and not os.path.isfile(os.path.join(out, e["name"], "process.json")):
        print("FAIL: %s: done without results" % e["name"]); bad = 1
    left = [f for f in os.listdir(os.path.join(out, e["name"])) if f.startswith(".kogei-run")]
    if left:
        print("FAIL: %s: staging folder left: %r" % (e["name"], left)); bad = 1
sys.exit(bad)
PYEOF
run "$KOGEI" collection run "$C/list3.csv" -o res --jobs 2
check "the next run completes the interrupted one" grep -q "4 done, 0 failed, 0 pending" "$T/out"

# ---- the Slurm engine's script and calls (stand-ins for sbatch and squeue) ------------------
mkdir -p bin
cat >bin/sbatch <<'EOF'
#!/bin/sh
echo "$*" >>"$FAKE_LOG"
case "$*" in *--dependency=*) echo 102 ;; *) echo "101;cluster" ;; esac
EOF
cat >bin/squeue <<'EOF'
#!/bin/sh
echo "squeue $*" >>"$FAKE_LOG"
exit 0
EOF
chmod +x bin/sbatch bin/squeue
export FAKE_LOG=$T/sbatch.log
expect_exit 0 env PATH="$T/bin:$PATH" "$KOGEI" collection run "$C/list.csv" \
	-o sl --engine slurm --jobs 3 --partition short --sbatch-args "--time=10 --mem=1G" --no-wait
check "--no-wait names both jobs" grep -q "job array 101 and job 102" "$T/out"
first=$(sed -n 1p sbatch.log) second=$(sed -n 2p sbatch.log)
case "$first" in
"--parsable --array=0-3%3 --output=$T/sl/.slurm/logs/task-%A_%a.out --partition=short --time=10 --mem=1G $T/sl/.slurm/collection.sbatch task") ;;
*) echo "FAIL: the array's sbatch: $first"; fail=1 ;;
esac
case "$second" in
"--parsable --dependency=afterany:101 --output=$T/sl/.slurm/logs/finish-%j.out --partition=short --time=10 --mem=1G $T/sl/.slurm/collection.sbatch finish") ;;
*) echo "FAIL: the record job's sbatch: $second"; fail=1 ;;
esac
check "job.json records both jobs" grep -q '"finish_job": "102"' sl/.slurm/job.json
check "the script is a shell script" sh -n sl/.slurm/collection.sbatch
# one task run as Slurm would: its entry done, its job the array's id and task
run env SLURM_ARRAY_JOB_ID=101 SLURM_ARRAY_TASK_ID=1 sh sl/.slurm/collection.sbatch task
check "the task's entry done with job slurm:101_1" grep -q '"job": "slurm:101_1"' sl/.collection/entries/second.json
run sh sl/.slurm/collection.sbatch finish
check "the record job's collection.json" grep -q '"engine": "slurm"' sl/collection.json
expect_exit 1 "$KOGEI" collection status sl
check "status counts the one task" grep -q "4 entries: 1 done, 0 failed, 3 pending" "$T/out"
# only the entries not done are submitted again
: >sbatch.log
expect_exit 0 env PATH="$T/bin:$PATH" "$KOGEI" collection run "$C/list.csv" \
	-o sl --engine slurm --no-wait
check "a resubmission holds the entries not done" grep -q -- "--array=0,2,3 " sbatch.log
# sbatch refusing the job: exit 3 with its message
cat >bin/sbatch <<'EOF'
#!/bin/sh
echo "sbatch: error: invalid partition specified: nope" >&2
exit 1
EOF
expect_exit 3 env PATH="$T/bin:$PATH" "$KOGEI" collection run "$C/list.csv" -o sl2 --engine slurm \
	--partition nope
check "sbatch's message shown" grep -q "invalid partition specified: nope" "$T/err"
expect_exit 3 env PATH=/nonexistent "$KOGEI" collection run "$C/list.csv" -o sl3 --engine slurm
exit $fail
