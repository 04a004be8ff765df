#!/bin/sh
# Object records (--meta) and provenance: kogei acquire stores a capture's --meta as its
# "meta" in session.json and refuses a malformed one naming it (exit 2, the session
# unchanged); kogei process records its own --meta as process.json "meta" (the run's,
# never merged with the captures'), gives each object its capture's and the chart's
# record to calibration.meta, and report.html shows the records at the top with
# HTML-special characters escaped; process.json's inputs carry absolute paths
# (the command run with relative ones) and their sha256.
# usage: test_process_meta.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
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
cd "$T" || exit 1
"$KOGEI" sim chart --layout cie-tcs-frame --spectra /usr/share/colord/ref/CIE-TCS.sp \
	--camera "$FIX/demo/site_camera.csv" --illuminant A --tilt 25 --width 800 --height 600 \
	-o chart.tif >/dev/null &&
"$KOGEI" sim image --materials default --camera "$FIX/demo/site_camera.csv" --illuminant A \
	--angle 30 --patch-size 40 --size 800x600 -o object.tif >/dev/null &&
"$KOGEI" acquire --camera "sim:chart.tif?$CAM&light=0" --out S --kind dark \
	--exposure 10000 --frames 3 --gain 0 >/dev/null &&
"$KOGEI" acquire --camera "sim:chart.tif?$CAM&uniform=0.6" --out S --kind flat \
	--exposure 10000 --frames 3 --gain 0 >/dev/null &&
"$KOGEI" acquire --camera "sim:chart.tif?$CAM" --out S --kind chart --exposure 10000 \
	--gain 0 --layout cie-tcs-frame --meta lighting='2 x LED 5000 K, 45/0' >/dev/null &&
"$KOGEI" acquire --camera "sim:object.tif?$CAM" --out S --kind object --exposure 10000 \
	--gain 0 --meta accession=1987.12.3 --meta 'title=<b>Bowl</b> & "lid" – 漆' \
	--meta x.custom_1=yes >/dev/null &&
"$KOGEI" measure --spectro sim:/usr/share/colord/ref/CIE-TCS.sp --chart cie-tcs-frame \
	--illuminant A --yes -o chart.cgats >/dev/null 2>&1 ||
"$KOGEI" measure --spectro sim:/usr/share/colord/ref/CIE-TCS.sp --chart cie-tcs-frame \
	--yes -o chart.cgats >/dev/null 2>&1 ||
	{ echo "FAIL: setting up the session"; exit 1; }

# Malformed records: refused with exit 2 naming --meta and the argument; nothing added.
before=$(sha256sum S/session.json)
refuse() { # WHAT ARG
	"$KOGEI" acquire --camera "sim:object.tif?$CAM" --out S --kind object --exposure 10000 \
		--gain 0 --meta "$2" >out.log 2>err.log
	rc=$?
	if [ $rc != 2 ] || ! grep -qF -- "--meta '" err.log || ! grep -qF "$3" err.log; then
		echo "FAIL: acquire --meta ($1): exit $rc, expected 2 and a message naming it:"
		cat err.log; fail=1
	fi
}
refuse "no =" 'title' 'expected KEY=VALUE'
refuse "bad key" 'ti tle=x' 'key: expected'
refuse "empty key" '=x' 'key: expected'
refuse "control character" "$(printf 'notes=a\tb')" 'control characters'
refuse "invalid UTF-8" "$(printf 'notes=a\377b')" 'UTF-8'
refuse "too long" "notes=$(head -c 4097 /dev/zero | tr '\0' a)" '4096 bytes'
# Characters that make a record display differently from its bytes: bidi overrides and
# isolates, zero-width and invisible characters, the BOM, line/paragraph separators.
for cp in '\342\200\256' '\342\200\213' '\357\273\277' '\342\200\250' '\342\200\251' \
	'\342\201\246' '\302\255' '\342\201\240'; do
	refuse "format character $cp" "$(printf "accession=1987${cp}321")" 'format character'
done
# A refused argument is echoed escaped: no control byte reaches the terminal.
refuse "escape sequence" "$(printf 'title=\033]0;x\007\033[2Jz\342\200\256')" '\x1B]0;x\x07\x1B[2Jz\u{202E}'
if LC_ALL=C grep -q "$(printf '[\033\007]')" err.log; then
	echo "FAIL: a refused --meta echoed control bytes to the terminal"; fail=1
fi
"$KOGEI" acquire --camera "sim:object.tif?$CAM" --out S --kind object --exposure 10000 \
	--gain 0 --meta title=a --meta title=b >out.log 2>err.log
rc=$?
[ $rc = 2 ] && grep -q "given twice" err.log ||
	{ echo "FAIL: a key given twice: exit $rc"; cat err.log; fail=1; }
[ "$(sha256sum S/session.json)" = "$before" ] ||
	{ echo "FAIL: a refused --meta changed session.json"; fail=1; }

"$PY" - S/session.json <<'PYEOF' || fail=1
import json, sys
caps = json.load(open(sys.argv[1]))["captures"]
by = {c["kind"]: c for c in caps}
ok = True
def check(cond, msg):
    global ok
    if not cond:
        print("FAIL: session.json:", msg); ok = False
check(by["object"].get("meta") == {"accession": "1987.12.3",
      "title": '<b>Bowl</b> & "lid" – 漆', "x.custom_1": "yes"},
      "object meta %r" % by["object"].get("meta"))
check(by["chart"].get("meta") == {"lighting": "2 x LED 5000 K, 45/0"},
      "chart meta %r" % by["chart"].get("meta"))
check("meta" not in by["dark"], "a capture without --meta has no meta")
sys.exit(0 if ok else 1)
PYEOF

# process: a malformed --meta refused before anything runs.
"$KOGEI" process S --spectra chart.cgats -o out --meta 'bad key=1' >out.log 2>err.log
rc=$?
[ $rc = 2 ] && grep -qF -- "--meta 'bad key=1'" err.log && [ ! -e out ] ||
	{ echo "FAIL: process --meta 'bad key=1': exit $rc"; cat err.log; fail=1; }
"$KOGEI" process S --spectra chart.cgats -o out --no-render --cube none --meta operator=K.\ Sato \
	--meta lighting=overridden >process.log 2>&1 || { cat process.log; echo "FAIL: process"; exit 1; }

"$PY" - out/process.json out/report.html "$T" <<'PYEOF' || fail=1
import hashlib, json, os, sys
pj = json.load(open(sys.argv[1]))
page = open(sys.argv[2], encoding="utf-8").read()
ok = True
def check(cond, msg):
    global ok
    if not cond:
        print("FAIL:", msg); ok = False
m = pj.get("meta")
check(m == {"lighting": "overridden", "operator": "K. Sato"},
      "process.json meta (the run's own) %r" % m)
check(pj["calibration"].get("meta") == {"lighting": "2 x LED 5000 K, 45/0"},
      "calibration.meta (the chart capture's) %r" % pj["calibration"].get("meta"))
objs = pj["objects"]
check(len(objs) == 1 and objs[0].get("meta", {}).get("accession") == "1987.12.3"
      and "operator" not in objs[0].get("meta", {}),
      "objects[0].meta %r" % [o.get("meta") for o in objs])
ins = pj["inputs"]
check(len(ins) >= 3, "inputs %r" % ins)
for i in ins:
    p = i["path"]
    check(os.path.isabs(p) and os.path.realpath(p) == p, "input path %r not absolute" % p)
    if os.path.isfile(p):
        check(hashlib.sha256(open(p, "rb").read()).hexdigest() == i["sha256"],
              "sha256 of %s" % p)
check(any(i["path"] == os.path.realpath(os.path.join(sys.argv[3], "chart.cgats"))
          for i in ins), "the --spectra input by its absolute path")
# The record at the top, before the summary, escaped.
rec, summ = page.find('id="record"'), page.find('id="summary"')
check(0 < rec < summ, "the record section is before the summary (%d, %d)" % (rec, summ))
check("&lt;b&gt;Bowl&lt;/b&gt; &amp; " in page and "<b>Bowl" not in page,
      "title not escaped in report.html")
check("1987.12.3" in page and "K. Sato" in page and "x.custom_1" in page,
      "record values shown")
sec = page[rec:summ]
check(sec.find("accession") < sec.find("title") < sec.find("x.custom_1") < sec.find("operator"),
      "known keys first, in order, the run's record after the object's")
sys.exit(0 if ok else 1)
PYEOF
# A stored record that is not one (edited by hand): the manifest is refused, naming it.
cp -r S S2 && rm -f S2/.lock
"$PY" - S2/session.json <<'PYEOF'
import json, sys
m = json.load(open(sys.argv[1]))
m["captures"][3]["meta"]["title"] = "a\tb"
json.dump(m, open(sys.argv[1], "w"))
PYEOF
"$KOGEI" process S2 --spectra chart.cgats -o out2 --cube none >out.log 2>err.log
rc=$?
[ $rc = 1 ] && grep -qF "S2/session.json: captures[3].meta.title: expected no control" err.log &&
	[ ! -e out2/process.json ] ||
	{ echo "FAIL: a control character in a stored record: exit $rc"; cat err.log; fail=1; }
[ $fail = 0 ] && echo "PASS: process-meta"
exit $fail
