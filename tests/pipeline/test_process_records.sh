#!/bin/sh
# Records a repository can trust, on a session of two objects and then three whose
# records differ in every field: process.json gives each object its own record and the
# run only what it was given; report.html shows each object's record in its own row and
# its own section (the first object's accession included, no other object's values in
# a section); no file of OUTDIR (binary ones included) names the staging folder or a
# path through the shell's working directory; each warning is recorded once, and the
# command line, process.json's warning_count and the report say the same number, on the
# first run and on an unchanged re-run.
# usage: test_process_records.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
ROOT=$2
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${3:-1}" json
case $KOGEI in /*) ;; *) KOGEI=$(pwd)/$KOGEI ;; esac
case $ROOT in /*) ;; *) ROOT=$(pwd)/$ROOT ;; esac
FIX=$ROOT/fixtures
kg_temp
CAM='format=bayer_rggb12&fullwell=20000&read=5&serial=site-1'
mkdir -p "$T/work/sub" && cd "$T/work" || exit 1
"$KOGEI" sim chart --layout cie-tcs-frame --spectra "$TCS" \
	--camera "$FIX/demo/site_camera.csv" --illuminant A --tilt 25 --width 640 --height 480 \
	-o chart.tif >/dev/null &&
"$KOGEI" sim image --materials default --camera "$FIX/demo/site_camera.csv" --illuminant A \
	--angle 30 --patch-size 30 --size 480x360 -o object.tif >/dev/null &&
# a dark at the chart's exposure and size only: the objects (smaller) have none, a
# warning of each object's
"$KOGEI" acquire --camera "sim:chart.tif?$CAM&light=0" --out S --kind dark \
	--exposure 10000 --frames 3 --gain 0 >/dev/null &&
"$KOGEI" acquire --camera "sim:chart.tif?$CAM&uniform=0.3" --out S --kind flat \
	--exposure 20000 --frames 3 --gain 0 >/dev/null &&
"$KOGEI" acquire --camera "sim:chart.tif?$CAM" --out S --kind chart --exposure 10000 \
	--frames 3 --gain 0 --layout cie-tcs-frame >/dev/null &&
"$KOGEI" acquire --camera "sim:object.tif?$CAM" --out S --kind object --exposure 10000 \
	--frames 3 --gain 0 --meta accession=AC-1111 --meta 'title=Title One' \
	--meta operator=Operator-A --meta date=2026-01-01 --meta rights=Rights-A \
	--meta notes=Notes-A >/dev/null &&
"$KOGEI" acquire --camera "sim:object.tif?$CAM" --out S --kind object --exposure 5000 \
	--frames 3 --gain 0 --meta accession=AC-2222 --meta 'title=Title Two' \
	--meta operator=Operator-B --meta date=2026-02-02 --meta rights=Rights-B \
	--meta notes=Notes-B >/dev/null &&
# one patch left unmeasured: a warning of the session's (a patch paired with nothing)
"$KOGEI" measure --spectro sim:$TCS --yes -o chart.cgats \
	--patches TCS01,TCS02,TCS03,TCS04,TCS05,TCS06,TCS07,TCS08,TCS09,TCS10,TCS11,TCS12,TCS13,TCS14 \
	>/dev/null 2>&1 ||
	{ echo "FAIL: setting up the session"; exit 1; }

# Run from a folder below, with relative paths: nothing recorded may go through it.
run_process() { # LOG
	(cd sub && "$KOGEI" process ../S --spectra ../chart.cgats -o ../results --no-render \
		--meta lighting=Lighting-Run >"$T/$1" 2>&1) ||
		{ cat "$T/$1"; echo "FAIL: kogei process"; exit 1; }
}

check_outdir() { # WHEN EXPECTED_OBJECTS LOG
	"$PY" - results "$T/$3" "$2" "$1" <<'PYEOF' || fail=1
import json, os, re, sys
out, log, nobj, when = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
ok = True
def check(cond, msg):
    global ok
    if not cond:
        print("FAIL (%s): %s" % (when, msg)); ok = False
records = [
    {"accession": "AC-1111", "title": "Title One", "operator": "Operator-A",
     "date": "2026-01-01", "rights": "Rights-A", "notes": "Notes-A"},
    {"accession": "AC-2222", "title": "Title Two", "operator": "Operator-B",
     "date": "2026-02-02", "rights": "Rights-B", "notes": "Notes-B"},
    {"accession": "AC-3333", "title": "Title Three", "operator": "Operator-C",
     "date": "2026-03-03", "rights": "Rights-C", "notes": "Notes-C"}][:nobj]
pj = json.load(open(os.path.join(out, "process.json")))
check(pj.get("meta") == {"lighting": "Lighting-Run"},
      "the run's meta is only its own --meta: %r" % pj.get("meta"))
objs = pj["objects"]
check(len(objs) == nobj, "%d objects, expected %d" % (len(objs), nobj))
for o, rec in zip(objs, records):
    check(o.get("meta") == rec, "%s: meta %r, expected %r" % (o["capture"], o.get("meta"), rec))

# The report: one row per object at the top, each object's section its own.
page = open(os.path.join(out, "report.html"), encoding="utf-8").read()
top = page[page.find('id="record"'):page.find('id="summary"')]
check(top, "no record section before the summary")
for i, rec in enumerate(records):
    m = re.search(r'<tr id="record-%d">(.*?)</tr>' % (i + 1), top, re.S)
    check(m is not None, "no row for object %d in the records table" % (i + 1))
    row = m.group(1) if m else ""
    for j, other in enumerate(records):
        for k, v in other.items():
            if i == j:
                check(v in row, "object %d's row lacks its %s %r" % (i + 1, k, v))
            else:
                check(v not in row, "object %d's row shows object %d's %s %r" % (i + 1, j + 1, k, v))
check("Lighting-Run" in top, "the run's record is not shown")
arts = re.findall(r'<article class="object" id="object-\d+">(.*?)</article>', page, re.S)
check(len(arts) == nobj, "%d object sections" % len(arts))
for i, art in enumerate(arts):
    for j, other in enumerate(records):
        for k, v in other.items():
            if i == j:
                check(v in art, "object %d's section lacks its %s %r" % (i + 1, k, v))
            else:
                check(v not in art, "object %d's section shows object %d's %s" % (i + 1, j + 1, k))

# Every file of OUTDIR, binary ones too: no staging folder, no path through the
# folder the command was run from, no path through OUTDIR's own name.
for dirpath, dirs, files in os.walk(out):
    for f in files:
        p = os.path.join(dirpath, f)
        data = open(p, "rb").read()
        for bad in (b".kogei-run", b"../results", b"sub/../", b'"results/'):
            check(bad not in data, "%s holds %r" % (p, bad))
for o in objs:
    lj = json.load(open(os.path.join(out, o["capture"], "labels.json")))
    for k, v in lj["files"].items():
        check(v is None or (v.startswith(o["capture"] + "/") and os.path.exists(os.path.join(out, v))),
              "labels.json files.%s = %r: expected a path below OUTDIR that exists" % (k, v))

# Warnings: each once, the same number everywhere.
session_w = pj["warnings"]
object_w = [w for o in objs for w in o["warnings"]]
total = len(session_w) + len(object_w)
check(len(set(session_w) & set(object_w)) == 0, "a warning listed twice: %r" %
      (set(session_w) & set(object_w)))
check(pj.get("warning_count") == total, "warning_count %r, lists hold %d" %
      (pj.get("warning_count"), total))
check(any("TCS15" in w for w in session_w), "no session warning for the unmeasured patch: %r" % session_w)
check(any(w for w in objs[1]["warnings"]), "no warning for the second object (no dark at its exposure)")
text = open(log, encoding="utf-8").read()
m = re.search(r"(\d+) warning\(s\)", text)
check(m and int(m.group(1)) == total, "the command line says %s, process.json %d" %
      (m.group(1) if m else None, total))
printed = [l for l in text.splitlines() if l.startswith("kogei process: warning: ")]
after = text.split("warning(s)", 1)[1] if "warning(s)" in text else ""
listed = [l for l in after.splitlines() if l.startswith("kogei process: warning: ")]
check(len(listed) == total, "%d warnings printed after the summary, expected %d" % (len(listed), total))
sm = re.search(r"Warnings</th><td>(\d+)", page)
check(sm and int(sm.group(1)) == total, "the report's summary says %s, expected %d" %
      (sm.group(1) if sm else None, total))
ws = page[page.find('id="warnings"'):]
check(ws.count("<li>") == total, "the report lists %d warnings, expected %d" % (ws.count("<li>"), total))
sys.exit(0 if ok else 1)
PYEOF
}

run_process first.log
check_outdir "two objects" 2 first.log
run_process rerun.log
grep -q "2 processed" "$T/rerun.log" && { echo "FAIL: the re-run processed the objects again"; fail=1; }
check_outdir "an unchanged re-run" 2 rerun.log
"$KOGEI" acquire --camera "sim:object.tif?$CAM" --out S --kind object --exposure 10000 \
	--frames 3 --gain 0 --meta accession=AC-3333 --meta 'title=Title Three' \
	--meta operator=Operator-C --meta date=2026-03-03 --meta rights=Rights-C \
	--meta notes=Notes-C >/dev/null || { echo "FAIL: acquire a third object"; exit 1; }
run_process third.log
grep -q "1 processed, 2 unchanged" "$T/third.log" ||
	{ echo "FAIL: the third object's run:"; tail -n 3 "$T/third.log"; fail=1; }
check_outdir "three objects, two unchanged" 3 third.log
[ $fail = 0 ] && echo "PASS: process-records"
exit $fail
