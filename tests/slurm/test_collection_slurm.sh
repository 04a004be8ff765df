#!/bin/sh
# kogei collection run --engine slurm on a real single-node Slurm (scripts/with-slurm.sh:
# Debian's slurmctld, slurmd and munge in a private network namespace): six small sim
# sessions, one without a chart (broken on purpose), as one job array throttled to 2
# and the dependent job that writes the record. Checks the record (engine slurm, each
# entry's job the array's task, the failure's reason, the logs under OUT/.slurm/logs/,
# collection.json written by the dependent job), then fixes the broken session and
# checks that only it runs again (an array of one task) while the others keep their
# job. Also --no-wait with status, and sbatch refusing a partition (exit 3). Skips (77)
# without the Slurm and munge packages or without root (unshare -n).
#
#   test_collection_slurm.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
ROOT=$2
case $KOGEI in /*) ;; *) KOGEI=$(pwd)/$KOGEI ;; esac
case $ROOT in /*) ;; *) ROOT=$(pwd)/$ROOT ;; esac

if [ -z "${KOGEI_SLURM_DIR:-}" ]; then
	kg_need "${3:-1}" "built without libapriltag or OpenCV (chart tags, demosaicing)"
	kg_need_tcs
	exec "$ROOT/scripts/with-slurm.sh" /bin/sh "$0" "$KOGEI" "$ROOT" "${3:-1}"
fi

# Inside the wrapper: SLURM_CONF and KOGEI_SLURM_DIR are set.
kg_python json
FIX=$ROOT/fixtures
. "$(dirname "$0")/../pipeline/collection_sessions.sh"
kg_temp
cd "$T" || exit 1
C=$T/col
coll_sessions "$C" 5 && coll_broken "$C" broken || { echo "FAIL: setting up the sessions"; exit 1; }
{
	echo "session,spectra,meta.accession"
	for i in 1 2 3 4 5; do echo "s$i,chart.cgats,K-$i"; done
	echo "broken,chart.cgats,K-6"
} >"$C/list.csv"

expect_exit 1 "$KOGEI" collection run "$C/list.csv" -o res --engine slurm --jobs 2
cat "$T/err"
check "the failure named on stderr" grep -q "broken (.*line 7): failed: .*no chart capture" "$T/err"
check "the counts" grep -q "6 entries: 5 done, 1 failed, 0 pending (6 run now)" "$T/out"
array1=$("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1]))["array_job"])' res/.slurm/job.json)
finish1=$("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1]))["finish_job"])' res/.slurm/job.json)
"$PY" - res "$array1" <<'PYEOF' || fail=1
import json, os, sys
out, array = sys.argv[1], sys.argv[2]
r = json.load(open(os.path.join(out, "collection.json")))
plan = json.load(open(os.path.join(out, ".collection", "plan.json")))
bad = []
if r["engine"] != "slurm":
    bad.append("engine %r" % r["engine"])
if r["counts"] != {"entries": 6, "done": 5, "failed": 1, "pending": 0}:
    bad.append("counts %r" % r["counts"])
for i, e in enumerate(r["entries"]):
    if e["job"] != "slurm:%s_%d" % (array, plan["entries"].index(
            next(p for p in plan["entries"] if p["name"] == e["name"]))):
        bad.append("%s: job %r, expected the array %s's task" % (e["name"], e["job"], array))
    if not os.path.isfile(os.path.join(out, ".slurm", "logs", "task-%s_%d.out" % (array, i))):
        bad.append("%s: no task log" % e["name"])
    if e["name"] != "broken":
        if e["status"] != "done" or len(e["objects"]) != 1:
            bad.append("%s: status %r" % (e["name"], e["status"]))
        elif e["objects"][0]["accession"] != "K-%s" % e["name"][1:]:
            bad.append("%s: accession %r" % (e["name"], e["objects"][0]["accession"]))
    elif e["status"] != "failed" or "no chart capture" not in (e["reason"] or ""):
        bad.append("broken: %r %r" % (e["status"], e["reason"]))
for m in bad:
    print("FAIL: collection.json: " + m)
sys.exit(1 if bad else 0)
PYEOF
check "the dependent job wrote the record" grep -q "6 entries: 5 done, 1 failed" \
	"res/.slurm/logs/finish-$finish1.out"
check "the sbatch script" [ -x res/.slurm/collection.sbatch ]
check "index.html" [ -s res/index.html ]

# the broken session fixed: only it runs, as an array of one task
cp res/collection.json first.json
coll_fix "$C" broken || { echo "FAIL: adding the chart"; fail=1; }
run "$KOGEI" collection run "$C/list.csv" -o res --engine slurm --jobs 2
check "only the fixed entry ran" grep -q "6 entries: 6 done, 0 failed, 0 pending (1 run now)" "$T/out"
check "an array of one task" grep -q '"tasks": 1' res/.slurm/job.json
"$PY" - first.json res/collection.json res/.slurm/job.json <<'PYEOF' || fail=1
import json, sys
a = {e["name"]: e for e in json.load(open(sys.argv[1]))["entries"]}
b = {e["name"]: e for e in json.load(open(sys.argv[2]))["entries"]}
array = json.load(open(sys.argv[3]))["array_job"]
bad = 0
for n in a:
    if n == "broken":
        if b[n]["status"] != "done" or not b[n]["job"].startswith("slurm:%s_" % array):
            print("FAIL: broken after the fix: %r %r" % (b[n]["status"], b[n]["job"])); bad = 1
    elif (a[n]["job"], a[n]["time"]) != (b[n]["job"], b[n]["time"]):
        print("FAIL: %s ran again: %r -> %r" % (n, a[n]["job"], b[n]["job"])); bad = 1
sys.exit(bad)
PYEOF

# --no-wait, then status while the array runs and after
sed 's/,K-1$/,K-1b/' "$C/list.csv" >"$C/list2.csv"
run "$KOGEI" collection run "$C/list2.csv" -o res --engine slurm --no-wait
check "--no-wait names the jobs" grep -q "submitted Slurm job array" "$T/out"
expect_exit 2 "$KOGEI" collection run "$C/list2.csv" -o res --engine slurm
check "a second run refused while the jobs are queued" grep -q "still queued or running" "$T/err"
i=0
while [ $i -lt 60 ] && ! "$KOGEI" collection status res >status.out 2>&1; do
	sleep 0.5
	i=$((i + 1))
done
check "status: all done after the --no-wait run" grep -q "6 entries: 6 done, 0 failed, 0 pending" status.out

# sbatch refusing: exit 3 with its message
expect_exit 3 "$KOGEI" collection run "$C/list2.csv" -o res3 --engine slurm --partition nosuch
check "sbatch's refusal shown" grep -qi "sbatch refused the job.*partition" "$T/err"
exit $fail
