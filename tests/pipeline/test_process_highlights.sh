#!/bin/sh
# kogei process, highlights above the diffuse white (a small sim session: chart 400x300,
# object 160x120 of the CIE test colours and urushi, read as RGB without a Bayer
# pattern so a pixel is its own). A rectangle of W x H pixels inside the lightest
# patch is made FACTOR times as bright (bright_image), FACTOR chosen so its Y is about
# 2 (twice the perfect diffuser's); the object captured at 0.4 of the chart's exposure
# so nothing saturates the sensor (kogei process scales it back). The truth: exactly
# those W x H lit pixels are above the diffuse white. Checked:
#  - the warning names the highlights and their share (W x H of the lit pixels), and
#    no warning calls them "outside eciRGB v2";
#  - process.json objects[].highlights: above_white = W x H, above_white_fraction =
#    W x H / counted, counted = estimate.lit, clipped_in_master = W x H (nothing else is
#    above the white in a channel), max_y > 1.5; master_linear's path;
#  - master_linear.tif read back by a TIFF reader of the test's own (LZW, the
#    floating-point predictor): 32-bit float RGB; every pixel of the rectangle above 1
#    in a channel, none outside it; the rectangle's mean over the rest of the patch's
#    = FACTOR within 2 % (linear, unclipped); master.tif at 65535 there;
#  - exiftool: the float master's SampleFormat, bits, linear profile, and the same
#    identity (XMP dc:identifier, ImageDescription, Artist) as master.tif;
#  - report.html: the highlights section with the share and the map inlined, the map
#    (highlights.png) not blank: red pixels (the highlight colour), at least W x H, and
#    grey ones.
# usage: test_process_highlights.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC HAVE_LCMS
#        BRIGHT_IMAGE
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
FIX=$2/fixtures
BRIGHT=$5
HERE=$(cd "$(dirname "$0")" && pwd)
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${3:-1}" numpy
kg_need "$4" "built without LittleCMS (-Dlcms): no master"
kg_temp
SIM_CAMERA='format=rgb16&bits=12&fullwell=20000&read=5&serial=site-1'

"$KOGEI" sim chart --layout cie-tcs-frame --spectra "$TCS" \
	--camera "$FIX/demo/site_camera.csv" --illuminant A --tilt 25 --tilt-axis 120 \
	--rotate 5 --blur 1 --vignetting 0.1 --seed 2 --width 400 --height 300 --fov 40 \
	--fill 0.85 --paper 0.85 --ink 0.03 --background 0.2 --white-level 0.9 \
	--noise none --depth float -o "$T/chart.tif" >/dev/null &&
"$KOGEI" sim image --spectra "$TCS" --materials default --only urushi \
	--camera "$FIX/demo/site_camera.csv" --illuminant A --patch-size 16 --gap 4 \
	--columns 5 --background 0 --white-level 0.9 --size 160x120 --noise none \
	--depth float -o "$T/object.tif" --truth-cube "$T/truth.hdr" >/dev/null ||
	{ echo "FAIL: simulated scenes"; exit 1; }
# the lightest patch (mean truth reflectance) and a rectangle 3 pixels inside it
"$PY" - "$T/truth.hdr" >"$T/rect" <<'PY' || { echo "FAIL: no patch found"; exit 1; }
import sys
import numpy as np
h = open(sys.argv[1]).read()
get = lambda k: int(h.split(k)[1].split("=")[1].split()[0])
w, l, b = get("samples"), get("lines"), get("bands")
cube = np.fromfile(sys.argv[1][:-4] + ".img", dtype="<f4").reshape(b, l, w)
mean = cube.mean(axis=0)
ys, xs = np.unravel_index(np.argmax(mean), mean.shape)
v = mean[ys, xs]
same = np.abs(mean - v) < 1e-6
# the patch: the connected run of equal pixels around the brightest one
x0 = xs
while x0 > 0 and same[ys, x0 - 1]:
    x0 -= 1
x1 = xs
while x1 + 1 < w and same[ys, x1 + 1]:
    x1 += 1
y0 = ys
while y0 > 0 and same[y0 - 1, x0]:
    y0 -= 1
y1 = ys
while y1 + 1 < l and same[y1 + 1, x0]:
    y1 += 1
assert x1 - x0 >= 12 and y1 - y0 >= 12, (x0, x1, y0, y1)
factor = 2.0 / v
# the patch, then the rectangle (x y w h) and the factor
print(x0, y0, x1 - x0 + 1, y1 - y0 + 1, x0 + 3, y0 + 3, x1 - x0 - 5, y1 - y0 - 7, "%.4f" % factor)
PY
read -r PX PY0 PW PH RX RY RW RH FACTOR <"$T/rect"
N=$((RW * RH))
echo "patch ${PW}x$PH at $PX,$PY0; brighter by $FACTOR: ${RW}x$RH at $RX,$RY ($N pixels)"
run_or_exit "$BRIGHT" "$T/object.tif" "$T/bright.tif" "$RX" "$RY" "$RW" "$RH" "$FACTOR"
S=$T/S
sim_acquire "$S" chart "$T/chart.tif" 10000 '' --layout cie-tcs-frame || fail=1
sim_acquire "$S" object "$T/bright.tif" 4000 '' --name obj --meta accession=2026.4.7 \
	--meta 'title=Bright coupon' --meta operator=tester || fail=1
sim_measure "$T/chart.cgats" || { echo "FAIL: kogei measure"; fail=1; }
[ $fail = 0 ] || exit 1

A=$T/A
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$A" --no-render
[ -s "$A/obj/master_linear.tif" ] || { echo "FAIL: no master_linear.tif"; cat "$T/err"; exit 1; }
grep "highlights" "$T/out" | head -3
"$PY" - "$A" "$N" "$RX" "$RY" "$RW" "$RH" "$PX" "$PY0" "$PW" "$PH" "$FACTOR" <<PY || fail=1
import json, re, sys
sys.path.insert(0, "$HERE")
import numpy as np
from tiff_png_read import read_tiff
A = sys.argv[1]
n, rx, ry, rw, rh, px, py, pw, ph = map(int, sys.argv[2:11])
factor = float(sys.argv[11])
j = json.load(open(A + "/process.json"))
o = [x for x in j["objects"] if x["capture"] == "obj"][0]
h = o["highlights"]
print("highlights:", json.dumps(h))
lit = o["estimate"]["lit"]
assert h["counted"] == lit and h["counted_what"] == "lit pixels", (h, lit)
assert h["above_white"] == n, ("above white", h["above_white"], "expected", n)
assert abs(h["above_white_fraction"] - n / lit) < 1e-12, h
assert h["clipped_in_master"] == n and abs(h["clipped_in_master_fraction"] - n / lit) < 1e-12, h
assert h["max_y"] > 1.5 and h["max_reflectance"] > 1, h
assert h["map"] == "obj/highlights.png", h
assert o["master_linear"]["path"] == "obj/master_linear.tif", o["master_linear"]
assert o["master"]["clipped_pixels"] >= n, o["master"]
w = [x for x in o["warnings"] if "highlights above the diffuse white" in x]
assert len(w) == 1, o["warnings"]
share = "%.1f %% of the lit pixels (%d of %d)" % (100 * n / lit, n, lit)
assert share in w[0], (share, w[0])
assert not [x for x in o["warnings"] if "outside eciRGB" in x], o["warnings"]
# the float master: above 1 exactly in the rectangle, FACTOR times the patch's rest
f, t = read_tiff(A + "/obj/master_linear.tif")
assert f.dtype == np.float32 and f.shape == (o["height"], o["width"], 3), (f.dtype, f.shape)
assert t[258] == (32, 32, 32) and t[339][0] == 3 and t[317][0] == 3, (t[258], t[339], t[317])
inside = np.zeros(f.shape[:2], bool)
inside[ry:ry + rh, rx:rx + rw] = True
above = f.max(axis=2) > 1
assert above[inside].all(), ("float master: pixels of the rectangle not above 1",
                             int((~above[inside]).sum()))
assert not above[~inside].any(), ("float master: above 1 outside the rectangle",
                                  int(above[~inside].sum()))
ring = np.zeros_like(inside)
ring[py + 1:py + ph - 1, px + 1:px + pw - 1] = True
ring &= ~inside
ratio = f[inside].mean(axis=0) / f[ring].mean(axis=0)
print("float master: rectangle max channel %.3f..%.3f; rectangle / rest of the patch: %s "
      "(factor %.4f)" % (f[inside].max(axis=1).min(), f[inside].max(), np.round(ratio, 4), factor))
assert (abs(ratio / factor - 1) < 0.02).all(), (ratio, factor)
m, mt = read_tiff(A + "/obj/master.tif")
assert m.dtype == np.dtype("<u2") or m.dtype.kind == "u", m.dtype
assert (m[inside].max(axis=1) == 65535).all(), "master.tif: the rectangle not at full scale"
print("OK: %d of %d lit pixels above the diffuse white (%.2f %%)" % (n, lit, 100 * n / lit))
PY
# the tags: a float, linear master with master.tif's identity
if command -v exiftool >/dev/null 2>&1; then
	exiftool -s -s -s -SampleFormat -BitsPerSample -ProfileDescription -XMP-dc:Identifier \
		-ImageDescription -Artist -XMP-kogei:Object "$A/obj/master_linear.tif" >"$T/lin" 2>&1
	exiftool -s -s -s -XMP-dc:Identifier -ImageDescription -Artist -XMP-kogei:Object \
		"$A/obj/master.tif" >"$T/m16" 2>&1
	cat "$T/lin"
	sed -n 1p "$T/lin" | grep -q "Float" &&
		sed -n 2p "$T/lin" | grep -q "^32 32 32$" &&
		sed -n 3p "$T/lin" | grep -q "eciRGB v2 linear" ||
		{ echo "FAIL: exiftool: master_linear.tif is not 32-bit float with the linear profile"; fail=1; }
	tail -n 4 "$T/lin" >"$T/lin_id"
	cmp -s "$T/lin_id" "$T/m16" && grep -q "^2026.4.7$" "$T/m16" && grep -q "^tester$" "$T/m16" ||
		{ echo "FAIL: exiftool: master_linear.tif's identity differs from master.tif's:"; cat "$T/lin_id" "$T/m16"; fail=1; }
	exiftool -validate -warning -a "$A/obj/master_linear.tif" >"$T/val" 2>&1
	grep -q "Validate *: OK" "$T/val" ||
		{ echo "FAIL: exiftool -validate master_linear.tif:"; cat "$T/val"; fail=1; }
else
	echo "exiftool not installed: the tag checks skipped"
fi
# the report: the section, the share, the map inlined and not blank
"$PY" - "$A" "$N" <<PY || fail=1
import base64, json, re, sys
sys.path.insert(0, "$HERE")
import numpy as np
from tiff_png_read import read_png
A, n = sys.argv[1], int(sys.argv[2])
page = open(A + "/report.html", encoding="utf-8").read()
o = [x for x in json.load(open(A + "/process.json"))["objects"] if x["capture"] == "obj"][0]
lit = o["highlights"]["counted"]
assert "<h4>Highlights above the diffuse white</h4>" in page, "no highlights section"
share = "%.1f %% of the lit pixels (%d of %d)" % (100 * n / lit, n, lit)
assert share in page, share
assert "Highlight map: red" in page, "no map caption"
png = open(A + "/obj/highlights.png", "rb").read()
imgs = re.findall(r'<img [^>]*alt="highlight map" src="data:image/png;base64,([^"]+)"', page)
assert imgs and base64.b64decode(imgs[0]) == png, "the map is not inlined in the report"
img = read_png(png).astype(int)
red = ((img[:, :, 0] == 0xe0) & (img[:, :, 1] == 0x10) & (img[:, :, 2] == 0x10)).sum()
grey = ((img[:, :, 0] == img[:, :, 1]) & (img[:, :, 1] == img[:, :, 2]) &
        (img[:, :, 0] > 20) & (img[:, :, 0] < 235)).sum()
print("highlights.png: %dx%d, %d red pixels, %d grey" % (img.shape[1], img.shape[0], red, grey))
assert red >= n, ("red pixels in the map", red, "expected at least", n)
assert grey > 1000, ("grey pixels (the object) in the map", grey)
PY
exit $fail
