#!/bin/sh
# conformance.json and the held-out colour accuracy: a chart session recorded with the
# sim devices (dark, flat, a colorchecker24-frame chart of known spectra) processed twice, once with the
# site camera's full well at 20000 electrons and once at 2000 (ten times the shot
# noise variance): the seven records with their fields; the L* noise of the neutral
# patches scales with the simulated noise (ratio of standard deviations near
# sqrt(10)); the OECF and white balance records are the worst |ΔL*| and ΔE(a*b*) of the
# neutral patches; the held-out (leave-one-out) colour accuracy is no better than the
# in-sample one and the verdicts grade it; --verify CAPTURE grades a second capture of
# the chart instead, and a name that is no capture is refused; the sfr and colour
# misregistration records are measured on the slanted tag sides (chart rotated 3°) with
# MTF50 in a plausible range and the edges listed in used, and are "not measured" with
# the reason for the same chart square to the sensor (no tilt, no rotation).
# A known tone response: the chart rendered again with each neutral of reflectance r
# written as r^0.9 (tone_image, relative to the white from the sim's truth) and given
# as --verify: the oecf record is graded on it and its per-patch ΔL* matches
# L*(r^0.9) - L*(r) within 0.2, the white balance stays near 0.
# Known added noise: the chart with Gaussian noise of 1 % and 2 % of the white in each
# channel (tone_image), captured by a sim RGB sensor without noise of its own (rgb16,
# full well 1e9, read 0) as chart and --verify capture: each neutral's pixel spread
# relative to its mean is 0.01 / r within 12 %, and its L* noise doubles (2.0 +- 0.15).
# A chart with neutral patches is needed for the tone, white balance and noise records.
# usage: test_conformance.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC TONE_IMAGE
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
FIX=$2/fixtures
kg_need "${3:-1}" "built without libapriltag or OpenCV (chart tags, demosaicing)"
kg_python
. "$(dirname "$0")/sim_session.sh"
kg_temp
# The 24 patches of colorchecker24-frame with smooth reflectances: 18 colours (bumps
# and steps over 400-700 nm) and 6 flat neutrals, the chart's bottom row.
"$PY" - "$T/chart.csv" <<'PY' || exit 1
import math, sys
nm = list(range(380, 731, 10))
rows = []
ids = ["%s%02d" % (r, c) for r in "ABCD" for c in range(1, 7)]
for k, pid in enumerate(ids):
    if pid[0] == "D":
        v = [0.9, 0.59, 0.36, 0.19, 0.09, 0.035][int(pid[1:]) - 1]
        r = [v] * len(nm)
    else:
        c = 410 + 16 * k
        r = [0.05 + 0.6 * math.exp(-((x - c) / (40 + 3 * k)) ** 2)
             + (0.25 / (1 + math.exp(-(x - 560 - k) / 15)) if k % 3 == 0 else 0) for x in nm]
    rows.append(pid + "," + pid + "," + ",".join("%.4f" % x for x in r))
open(sys.argv[1], "w").write("patch,name," + ",".join(map(str, nm)) + "\n" + "\n".join(rows) + "\n")
PY
"$KOGEI" sim chart --layout colorchecker24-frame --spectra "$T/chart.csv" \
	--camera "$FIX/demo/site_camera.csv" --illuminant D50 --tilt 10 --rotate 3 --seed 2 \
	--width 800 --height 600 --fov 40 --fill 0.85 --paper 0.85 --ink 0.03 \
	--background 0.2 --white-level 0.9 --noise none --depth float -o "$T/chart.tif" \
	--truth "$T/truth.cgats" >/dev/null || { echo "FAIL: simulated chart"; exit 1; }
# the white: the D01 neutral (reflectance 0.9) without vignetting, divided by 0.9
W=$("$PY" - "$T/truth.cgats" <<'PY'
import sys
lines = open(sys.argv[1]).read().split("\n")
fmt = lines[lines.index("BEGIN_DATA_FORMAT") + 1].split()
for l in lines[lines.index("BEGIN_DATA") + 1:lines.index("END_DATA")]:
    f = dict(zip(fmt, l.split()))
    if f["SAMPLE_ID"] == "D01":
        print(" ".join("%.6g" % (float(f["FLAT_" + c]) / 0.9) for c in "RGB"))
PY
)
# shellcheck disable=SC2086
"$4" "$T/chart.tif" "$T/tone.tif" 0.9 $W || { echo "FAIL: tone_image ($W)"; exit 1; }
"$KOGEI" sim chart --layout colorchecker24-frame --spectra "$T/chart.csv" \
	--camera "$FIX/demo/site_camera.csv" --illuminant D50 --tilt 0 --rotate 0 --seed 2 \
	--width 800 --height 600 --fov 40 --fill 0.85 --paper 0.85 --ink 0.03 \
	--background 0.2 --white-level 0.9 --noise none --depth float -o "$T/square.tif" \
	>/dev/null || { echo "FAIL: simulated square chart"; exit 1; }
SIM_CAMERA="format=bayer_rggb12&fullwell=20000&read=5&serial=site-1"
S=$T/SQ
sim_acquire "$S" dark "$T/square.tif" 10000 '&light=0' 2>/dev/null || fail=1
sim_acquire "$S" flat "$T/square.tif" 10000 '&uniform=0.6' 2>/dev/null || fail=1
sim_acquire "$S" chart "$T/square.tif" 10000 '' --layout colorchecker24-frame 2>/dev/null ||
	fail=1
"$KOGEI" process "$S" --spectra "$T/chart.csv" -o "$T/OSQ" >"$T/out" 2>"$T/err" ||
	{ echo "FAIL: process (square chart)"; cat "$T/err"; fail=1; }
for fw in 20000 2000; do
	SIM_CAMERA="format=bayer_rggb12&fullwell=$fw&read=5&serial=site-1"
	S=$T/S$fw
	sim_acquire "$S" dark "$T/chart.tif" 10000 '&light=0' 2>/dev/null || fail=1
	sim_acquire "$S" flat "$T/chart.tif" 10000 '&uniform=0.6' 2>/dev/null || fail=1
	sim_acquire "$S" chart "$T/chart.tif" 10000 '' --layout colorchecker24-frame 2>/dev/null ||
		fail=1
	"$KOGEI" process "$S" --spectra "$T/chart.csv" -o "$T/O$fw" >"$T/out" 2>"$T/err" ||
		{ echo "FAIL: process ($fw)"; cat "$T/err"; fail=1; }
done
# a second capture of the chart (other noise) to verify with; and a refused name
S=$T/S20000
sim_acquire "$S" chart "$T/chart.tif" 10000 '&seed=5' --layout colorchecker24-frame 2>/dev/null ||
	fail=1
"$KOGEI" process "$S" --spectra "$T/chart.csv" --chart chart-0001 --verify chart-0002 \
	-o "$T/OV" >"$T/out" 2>"$T/err" || { echo "FAIL: process --verify"; cat "$T/err"; fail=1; }
sim_acquire "$S" chart "$T/tone.tif" 10000 '&seed=7' --layout colorchecker24-frame 2>/dev/null ||
	fail=1
"$KOGEI" process "$S" --spectra "$T/chart.csv" --chart chart-0001 --verify chart-0003 \
	-o "$T/OT" >"$T/out" 2>"$T/err" || { echo "FAIL: process --verify (tone)"; cat "$T/err"; fail=1; }
"$4" "$T/chart.tif" "$T/noise1.tif" 1 $W 0.01 11 && "$4" "$T/chart.tif" "$T/noise2.tif" 1 $W 0.02 12 ||
	{ echo "FAIL: tone_image (noise)"; exit 1; }
SIM_CAMERA="format=rgb16&fullwell=1e9&read=0&serial=site-2"
SN=$T/SN
sim_acquire "$SN" dark "$T/noise1.tif" 10000 '&light=0' 2>/dev/null || fail=1
sim_acquire "$SN" flat "$T/noise1.tif" 10000 '&uniform=0.6' 2>/dev/null || fail=1
sim_acquire "$SN" chart "$T/noise1.tif" 10000 '' --layout colorchecker24-frame 2>/dev/null || fail=1
sim_acquire "$SN" chart "$T/noise2.tif" 10000 '' --layout colorchecker24-frame 2>/dev/null || fail=1
"$KOGEI" process "$SN" --spectra "$T/chart.csv" --chart chart-0001 --verify chart-0002 \
	-o "$T/ON" >"$T/out" 2>"$T/err" || { echo "FAIL: process (known noise)"; cat "$T/err"; fail=1; }
"$KOGEI" process "$S" --spectra "$T/chart.csv" --chart chart-0001 --verify nosuch \
	-o "$T/OX" >"$T/out" 2>"$T/err"
[ $? = 1 ] && grep -q -- "--verify nosuch" "$T/err" && [ ! -e "$T/OX/conformance.json" ] ||
	{ echo "FAIL: --verify of no capture not refused"; cat "$T/err"; fail=1; }
[ $fail = 0 ] || exit 1
"$PY" - "$T/OV" <<'PY' || fail=1
import json, sys
c = json.load(open(sys.argv[1] + "/conformance.json"))
r = {x["id"]: x for x in c["characteristics"]}["colour_accuracy"]
print("--verify: ΔE00 D50 mean %.3f max %.3f on %d patches (in-sample mean %.3f)"
      % (r["verify"]["mean"], r["verify"]["max"], r["verify"]["n"], r["in_sample"]["mean"]))
assert r["graded_on"] == "verify", r
assert r["verify"]["n"] >= 20 and len(r["used"]) == r["verify"]["n"], r
assert abs(r["value"] - r["verify"]["mean"]) < 1e-12, r
p = json.load(open(sys.argv[1] + "/process.json"))["calibration"]["patches"]
assert any(isinstance(x.get("de00_d50_verify"), float) for x in p), "no de00_d50_verify"
page = open(sys.argv[1] + "/report.html").read()
assert "held-out (verification capture)" in page and "not a certification" in page
PY
"$PY" - "$T/OT" <<'PY' || fail=1
import json, sys
def lstar(y):
    return 116 * y ** (1 / 3) - 16 if y > (6 / 29) ** 3 else 903.3 * y
c = json.load(open(sys.argv[1] + "/conformance.json"))
recs = {x["id"]: x for x in c["characteristics"]}
p = json.load(open(sys.argv[1] + "/process.json"))["calibration"]["patches"]
neut = [x for x in p if x["neutral"] and isinstance(x.get("dL_verify"), float)]
assert len(neut) == 6, [x["id"] for x in neut]
worst = 0
for x in neut:
    r = sum(x["measured"]) / len(x["measured"])      # flat: Y / Yn = r
    want = lstar(r ** 0.9) - lstar(r)
    print("tone %s: r %.3f, ΔL* %.3f (known %.3f)" % (x["id"], r, x["dL_verify"], want))
    assert abs(x["dL_verify"] - want) < 0.2, (x["id"], x["dL_verify"], want)
    worst = max(worst, abs(want))
o = recs["oecf"]
assert o["graded_on"] == "verify" and sorted(o["used"]) == sorted(x["id"] for x in neut), o
assert abs(o["value"] - worst) < 0.2, (o["value"], worst)
assert recs["white_balance"]["graded_on"] == "verify" and recs["white_balance"]["value"] < 1.5, \
    recs["white_balance"]
print("tone r^0.9: oecf %.3f (known %.3f; %s, %d stars), white balance %.3f"
      % (o["value"], worst, o["level"], o["stars"], recs["white_balance"]["value"]))
PY
"$PY" - "$T/ON" <<'PY' || fail=1
import json, sys
c = json.load(open(sys.argv[1] + "/conformance.json"))
n = {x["id"]: x for x in c["characteristics"]}["noise"]
p = json.load(open(sys.argv[1] + "/process.json"))["calibration"]["patches"]
neut = [x for x in p if x["neutral"] and isinstance(x.get("noise_L_verify"), float)]
assert len(neut) == 6, [x["id"] for x in neut]
for x in neut:
    r = sum(x["measured"]) / len(x["measured"])
    rel = [x["sd"][k] / x["rgb"][k] for k in range(3)]
    ratio = x["noise_L_verify"] / x["noise_L"]
    print("noise %s: r %.3f, spread/mean %s (known %.4f), L* noise %.3f -> %.3f (x%.3f)"
          % (x["id"], r, " ".join("%.4f" % v for v in rel), 0.01 / r, x["noise_L"],
             x["noise_L_verify"], ratio))
    for v in rel:
        assert abs(v / (0.01 / r) - 1) < 0.12, (x["id"], rel, 0.01 / r)
    assert abs(ratio - 2.0) < 0.15, (x["id"], ratio)
assert n["graded_on"] == "verify", n
assert abs(n["value"] - max(x["noise_L_verify"] for x in neut)) < 1e-9, n
PY
"$PY" - "$T/O20000" "$T/O2000" <<'PY' || fail=1
import json, math, sys
ids = ["oecf", "white_balance", "illuminance_non_uniformity", "noise", "colour_accuracy",
       "sfr", "colour_misregistration"]
fields = ["id", "value", "unit", "aim", "tolerance", "level", "stars", "used", "measured",
          "note"]
def load(o):
    c = json.load(open(o + "/conformance.json"))
    assert "not a certification" in c["caveat"], c["caveat"]
    recs = {r["id"]: r for r in c["characteristics"]}
    assert sorted(recs) == sorted(ids), sorted(recs)
    for r in recs.values():
        for f in fields:
            assert f in r, (r["id"], f)
        assert r["level"] in (None, "A", "B", "C"), r
        assert r["stars"] in (0, 1, 2, 3, 4), r
    p = json.load(open(o + "/process.json"))["calibration"]
    return recs, p
a, pa = load(sys.argv[1])
b, pb = load(sys.argv[2])
# sfr and misregistration: measured on the tag sides of the rotated chart
s, m = a["sfr"], a["colour_misregistration"]
assert s["measured"] and isinstance(s["value"], float), s
assert len(s["used"]) >= 2, s["used"]
assert sorted(s["used"]) == sorted(e["edge"] for e in s["edges"] if "mtf50" in e), s
assert all(u.startswith("tag") for u in s["used"]), s["used"]
assert 0.05 < s["mtf50"] < 0.5, s["mtf50"]
assert s["mtf50"] < s["mtf10"] <= 1.0, s
assert 0 < s["efficiency"] <= 1 and abs(s["value"] - 100 * s["efficiency"]) < 1e-9, s
# graded on the published limits: sampling efficiency ISO >= 85/80/70 %, FADGI
# > 90/80/70/60 %; misregistration FADGI (2010) < 0.33/0.5/0.8 px, no ISO limit
def iso_hi(v, lim):
    return next((lv for lv, x in zip("ABC", lim) if v >= x), None)
def fadgi(v, lim, hi):
    return next((4 - k for k, x in enumerate(lim) if (v > x if hi else v < x)), 0)
assert s["level"] == iso_hi(s["value"], (85, 80, 70)), s
assert s["stars"] == fadgi(s["value"], (90, 80, 70, 60), True), s
assert s["tolerance"]["higher_is_better"] and s["tolerance"]["iso19264_1"]["A"] == 85, s
assert "ISO 19264-1" in s["tolerance"]["source"]["iso19264_1"], s["tolerance"]
assert m["measured"] and 0 <= m["value"] < 1.0 and m["used"] == s["used"], m
assert m["level"] is None and "no published limit found" in m["note"], m
assert m["stars"] == fadgi(m["value"], (0.33, 0.5, 0.8, float("inf")), False), m
print("sfr: %d edges, median MTF50 %.4f, MTF10 %.4f cy/px, efficiency %.1f %% (%s, %d "
      "stars); misregistration %.3f px (%d stars)"
      % (len(s["used"]), s["mtf50"], s["mtf10"], s["value"], s["level"], s["stars"],
         m["value"], m["stars"]))
for rid in ("oecf", "white_balance", "noise", "colour_accuracy", "illuminance_non_uniformity"):
    assert a[rid]["measured"] and isinstance(a[rid]["value"], float), a[rid]
# oecf and white balance: the worst over the neutral patches of process.json
neut = [x for x in pa["patches"] if x["neutral"] and x["dL"] is not None]
assert len(neut) >= 1, "no neutral patch"
assert abs(a["oecf"]["value"] - max(abs(x["dL"]) for x in neut)) < 1e-9, a["oecf"]
assert abs(a["white_balance"]["value"] - max(x["dab"] for x in neut)) < 1e-9
assert sorted(a["oecf"]["used"]) == sorted(x["id"] for x in neut), a["oecf"]["used"]
# the sim camera's response is linear and the neutrals flat spectra, which the
# calibration represents: the tone deviation is near 0 (level A, 4 stars), the white
# balance error small
assert a["oecf"]["value"] < 0.5 and a["oecf"]["level"] == "A" and a["oecf"]["stars"] == 4, a["oecf"]
assert a["white_balance"]["value"] < 2, a["white_balance"]
assert len(neut) == 6, [x["id"] for x in neut]
# noise: the standard deviation of shot noise goes as 1/sqrt(full well)
ratio = b["noise"]["value"] / a["noise"]["value"]
print("L* noise: %.4f (full well 20000), %.4f (2000), ratio %.2f (sqrt 10 = 3.16)"
      % (a["noise"]["value"], b["noise"]["value"], ratio))
assert 2.0 < ratio < 4.5, ratio
# held-out against in-sample
c = a["colour_accuracy"]
print("ΔE00 D50 in-sample mean %.3f p90 %.3f max %.3f; held-out mean %.3f p90 %.3f max %.3f"
      % (c["in_sample"]["mean"], c["in_sample"]["p90"], c["in_sample"]["max"],
         c["held_out"]["mean"], c["held_out"]["p90"], c["held_out"]["max"]))
assert c["graded_on"] == "held-out", c
assert c["held_out"]["mean"] >= c["in_sample"]["mean"], c
assert c["held_out"]["max"] >= c["in_sample"]["max"] - 1e-9, c
assert abs(c["value"] - c["held_out"]["mean"]) < 1e-12, c
assert c["cielab"]["illuminant"] == "CIE D50", c
print("oecf %.3f (%s, %d stars), white balance %.3f, non-uniformity %.3f %%"
      % (a["oecf"]["value"], a["oecf"]["level"], a["oecf"]["stars"],
         a["white_balance"]["value"], a["illuminance_non_uniformity"]["value"]))
PY
"$PY" - "$T/OSQ" <<'PY' || fail=1
import json, sys
c = json.load(open(sys.argv[1] + "/conformance.json"))
recs = {x["id"]: x for x in c["characteristics"]}
for rid in ("sfr", "colour_misregistration"):
    r = recs[rid]
    assert not r["measured"] and r["value"] is None and r["used"] == [], r
    assert r["note"].startswith("not measured") and "square to the sensor" in r["note"], r
print("square chart: sfr %s" % recs["sfr"]["note"])
PY
# An over-exposed chart (x 1.6: the white patch clipped on the sensor): no
# characteristic is graded from a patch chart detection flagged; each such patch is
# listed as left out, with why; nor from a clipped tag edge (the sfr and the
# misregistration not measured, every tag side left out as clipped).
SIM_CAMERA="format=bayer_rggb12&fullwell=20000&read=5&serial=site-1"
S=$T/SOVER
sim_acquire "$S" dark "$T/chart.tif" 16000 '&light=0' 2>/dev/null || fail=1
sim_acquire "$S" flat "$T/chart.tif" 16000 '&uniform=0.6' 2>/dev/null || fail=1
sim_acquire "$S" chart "$T/chart.tif" 16000 '' --layout colorchecker24-frame 2>/dev/null ||
	fail=1
if "$KOGEI" process "$S" --spectra "$T/chart.csv" -o "$T/OOVER" >"$T/out" 2>"$T/err"; then
	"$PY" - "$T/OOVER" <<'PY' || fail=1
import json, sys
pj = json.load(open(sys.argv[1] + "/process.json"))
flagged = {p["id"] for p in pj["calibration"]["patches"] if p.get("flags")}
assert "D01" in flagged, ("the over-exposed white is not flagged", pj["calibration"]["patches"][18])
c = json.load(open(sys.argv[1] + "/conformance.json"))
recs = {x["id"]: x for x in c["characteristics"]}
for rid in ("oecf", "white_balance", "noise", "colour_accuracy"):
    r = recs[rid]
    used = set(r["used"])
    assert not used & flagged, (rid, "graded from flagged patches", used & flagged)
    out = {x["id"] for x in r["left_out"]}
    assert "D01" in out and all(x["why"] for x in r["left_out"]), (rid, r["left_out"])
print("over-exposed chart: %s flagged, left out of every grade; oecf %.3f on %s"
      % (sorted(flagged), recs["oecf"]["value"], recs["oecf"]["used"]))
# the paper (0.85 x the white level 0.9, x 1.6) clips too: every tag side's white ring
# is clipped, so no edge grades the sfr or the misregistration (the old code read
# 76.6 % and 0.32 px from the clipped edges); each is left out as clipped, with why
s, m = recs["sfr"], recs["colour_misregistration"]
assert not s["measured"] and not m["measured"] and m["value"] is None, (s, m)
assert s["left_out"] and all(x["why"].startswith("clipped") for x in s["left_out"]), s
assert m["left_out"] == s["left_out"] and "clipped" in s["note"], (s["note"], m)
print("over-exposed chart: sfr %s" % s["note"])
PY
else
	echo "FAIL: process (over-exposed chart)"; cat "$T/err"; fail=1
fi
# the report: both figures, the verdicts on the held-out ones, the caveat
R=$T/O20000/report.html
for pat in 'id="heldout"' 'held-out (leave-one-out)' 'FADGI 4-star (held-out)' \
	'not a certification' 'id="conformance"' 'colour_misregistration'; do
	grep -q -- "$pat" "$R" || { echo "FAIL: report lacks $pat"; fail=1; }
done
exit $fail
