#!/bin/sh
# Flare with known truth: kogei sim patches --flare F adds F of each channel's white to
# every reading of a ColorChecker (BabelColor's published spectra, the demo's site
# camera, D65, shot and read noise); kogei calib reference must measure it from the
# neutral row within 1 % of white, remove it when that validates better (leave-one-out
# dE00, recorded), keep values without flare, refuse a frame above --max-flare naming
# flare and the measured values, and kogei calib camera must measure and remove the
# site chart's own flare against the reference's flare-free values.
# usage: test_flare.sh KOGEI SOURCE_ROOT
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
case $KOGEI in /*) ;; *) KOGEI=$(pwd)/$KOGEI ;; esac
kg_need_reference "$2" charts/colorchecker24_babelcolor_avg.csv
kg_python json
kg_temp
SP=$REF/charts/colorchecker24_babelcolor_avg.csv
cd "$T" || exit 1
sim() { # FLARE OUT [SEED]
	"$KOGEI" sim patches --spectra "$SP" --camera demo-site --illuminant D65 \
		--noise 20000:5:12 --seed "${3:-1}" --flare "$1" -o "$2" >/dev/null ||
		{ echo "FAIL: sim patches --flare $1"; exit 1; }
}
# measured FLARE REF.json LOG [REMOVED]: the flare in REF.json within 0.01 of FLARE in
# every channel; REMOVED 1: it was removed and that validated better, 0: kept
measured() {
	"$PY" - "$@" <<'PYEOF' || fail=1
import json, sys
truth, path, log = float(sys.argv[1]), sys.argv[2], sys.argv[3]
want = sys.argv[4] if len(sys.argv) > 4 else None
r = json.load(open(path))["flare"]
w = r["training"]["white_fraction"]
print("flare %.3f: measured %s, removed %s, leave-one-out dE00 kept %s, removed %s"
      % (truth, ["%.4f" % x for x in w], r["removed"], r["loo_de00_kept"], r["loo_de00_removed"]))
ok = all(abs(x - truth) < 0.01 for x in w)
if not ok:
    print("FAIL: flare %.3f measured %r (expected within 0.01)" % (truth, w))
if want == "1" and not (r["removed"] and r["loo_de00_removed"] < r["loo_de00_kept"]):
    ok = False; print("FAIL: flare %.3f not removed, or removing it did not validate better: %r" % (truth, r))
if want == "0" and r["removed"]:
    ok = False; print("FAIL: flare %.3f removed (expected kept): %r" % (truth, r))
text = open(log).read()
if "flare: the %d neutral patches meet zero at" % len(r["training"]["neutrals"]) not in text:
    ok = False; print("FAIL: the flare is not reported by calib reference:\n" + text)
sys.exit(0 if ok else 1)
PYEOF
}
for f in 0 0.03 0.05; do
	for seed in 1 2; do
		sim "$f" "f$f-$seed.cgats" "$seed"
		run "$KOGEI" calib reference --spectra "$SP" --rgb "f$f-$seed.cgats" -o "r$f-$seed.json" \
			--basis auto --method auto
		cp "$T/err" "log$f-$seed" 2>/dev/null; cat "$T/out" >>"log$f-$seed"
		case $f in 0) measured "$f" "r$f-$seed.json" "log$f-$seed" ;;
		*) measured "$f" "r$f-$seed.json" "log$f-$seed" 1 ;; esac
	done
done
# --keep-flare: measured, never removed
run "$KOGEI" calib reference --spectra "$SP" --rgb f0.05-1.cgats -o keep.json --keep-flare
cat "$T/out" "$T/err" >keep.log
measured 0.05 keep.json keep.log 0
# Too much flare: refused naming flare and the measured values; accepted with a limit above
sim 0.12 f0.12.cgats
expect_exit 1 "$KOGEI" calib reference --spectra "$SP" --rgb f0.12.cgats -o big.json
grep -q "flare: the chart's 6 neutral patches" "$T/err" && grep -q "above the 8.0 %" "$T/err" &&
	grep -Eq "1[12]\.[0-9] % \(R\)" "$T/err" ||
	{ echo "FAIL: a 12 % flare not refused as flare:"; cat "$T/err"; fail=1; }
[ ! -e big.json ] || { echo "FAIL: a refused fit wrote big.json"; fail=1; }
run "$KOGEI" calib reference --spectra "$SP" --rgb f0.12.cgats -o big.json --max-flare 15
cat "$T/out" "$T/err" >big.log
measured 0.12 big.json big.log 1
run "$KOGEI" calib reference --spectra "$SP" --rgb f0.12.cgats -o none.json --max-flare none
for bad in 0 abc 101; do
	expect_exit 2 "$KOGEI" calib reference --spectra "$SP" --rgb f0.12.cgats -o bad.json \
		--max-flare "$bad"
	grep -q -- "--max-flare" "$T/err" || { echo "FAIL: --max-flare $bad not named"; fail=1; }
done
# The site chart's own flare (4 %) against a reference whose flare (3 %) was removed:
# measured from the neutral patches within 1 %, subtracted before M2, recorded.
sim 0.04 site.cgats 7
run "$KOGEI" calib camera --reference r0.03-1.json --rgb site.cgats -o cam.json
"$PY" - cam.json <<'PYEOF' || fail=1
import json, sys
s = json.load(open(sys.argv[1]))["site"]
w = s["flare"]["white_fraction"]
print("site flare 0.040: measured %s, removed %s, M2 residual %.4f"
      % (["%.4f" % x for x in w], s["flare_removed"], s["residual_relative"]))
ok = s["flare_removed"] and all(abs(x - 0.04) < 0.01 for x in w)
if not ok:
    print("FAIL: the site chart's flare: %r" % s["flare"])
sys.exit(0 if ok else 1)
PYEOF
[ $fail = 0 ] && echo "PASS: calib-flare"
exit $fail
