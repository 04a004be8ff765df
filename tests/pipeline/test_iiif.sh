#!/bin/sh
# The IIIF access copy and manifest, served by a real image server and opened in a real
# viewer. A small sim session (chart 400x300, object 600x400 of the library's
# materials) is processed with --iiif-base and --files-base on a free port of
# 127.0.0.1; then (iiif_check.py):
#  - access.tif read IFD by IFD (a reader of the test's own): 8-bit RGB, 256 x 256
#    JPEG tiles, each level half the one before (rounded either way) down to the first
#    that fits one tile, the identity's XMP (dc:identifier the accession);
#  - manifest.json: IIIF Presentation 3 (@context, Manifest, label the title, the
#    metadata: accession, materials with their shares as process.json has them, the
#    held-out dE00, date, operator, the legend), one Canvas of the master's size, the
#    painting annotation of the access copy with its image service at
#    --iiif-base/<object>/access.tif, a second painting annotation of labels.png;
#  - iipsrv (Debian iipimage-server) behind lighttpd's FastCGI (iiif_serve.sh, both
#    started and stopped here): info.json's width and height are the master's, its
#    tiles 256 with the scale factors of the pyramid's levels; a region at half size,
#    decoded, against the master rendered to sRGB by LittleCMS's tificc through its
#    own profile and averaged 2 x 2: mean CIEDE2000 <= 1;
#  - kogei collection run --iiif-base --files-base on two sessions: each entry's
#    manifest under URL/<name>, OUT/collection-manifest.json a IIIF Collection of them,
#    and iipsrv serving OUT answers each entry's image service;
#  - without --iiif-base the manifest's ids are relative and its summary and
#    process.json say so; --access-compression deflate writes deflate tiles; bad
#    values are refused naming the option;
# and in "viewer" mode, the manifest in OpenSeadragon (npm, .tools/openseadragon) in
# headless Chromium from the same server (iiif_browser.py): a screenshot not blank,
# tiles from iipsrv, the label layer toggled on and off changing the picture.
# usage: test_iiif.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC HAVE_LCMS HAVE_VIPS
#        server|viewer
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
ROOT=$2
MODE=${6:-server}
here=$(cd "$(dirname "$0")" && pwd)
case $KOGEI in /*) ;; *) KOGEI=$(pwd)/$KOGEI ;; esac
case $ROOT in /*) ;; *) ROOT=$(pwd)/$ROOT ;; esac
FIX=$ROOT/fixtures
. "$here/sim_session.sh"
. "$here/iiif_serve.sh"
. "$here/collection_sessions.sh"
sim_session_needs "${3:-1}" numpy
kg_need "$4" "built without LittleCMS (-Dlcms): no master, so no access copy"
kg_need "$5" "built without libvips (-Dvips): no access copy (Debian package libvips-dev)"
iiif_need
command -v tificc >/dev/null || kg_skip "tificc is not installed (Debian package liblcms2-utils)"
command -v vips >/dev/null || kg_skip "vips is not installed (Debian package libvips-tools)"
OSD=$ROOT/.tools/openseadragon/node_modules/openseadragon/build/openseadragon
if [ "$MODE" = viewer ]; then
	[ -f "$OSD/openseadragon.min.js" ] ||
		kg_skip "OpenSeadragon is not installed: scripts/setup.sh puts it in .tools/openseadragon"
	. "$here/../chromium.sh"
fi
T=$(mktemp -d) || exit 1
trap 'iiif_stop; [ "$MODE" = viewer ] && chromium_cleanup; [ -n "${KEEP:-}" ] || rm -rf "$T"' EXIT

"$KOGEI" sim chart --layout cie-tcs-frame --spectra "$TCS" \
	--camera "$FIX/demo/site_camera.csv" --illuminant A --tilt 25 --tilt-axis 120 \
	--rotate 5 --blur 1 --vignetting 0.1 --seed 2 --width 400 --height 300 --fov 40 \
	--fill 0.85 --paper 0.85 --ink 0.03 --background 0.2 --white-level 0.9 \
	--noise none --depth float -o "$T/chart.tif" >/dev/null &&
"$KOGEI" sim image --materials default --camera "$FIX/demo/site_camera.csv" \
	--illuminant A --angle 30 --patch-size 60 --gap 20 --columns 6 --background 0.3 \
	--white-level 0.9 --size 600x400 --noise none --depth float -o "$T/object.tif" \
	>/dev/null || { echo "FAIL: simulated scenes"; exit 1; }
S=$T/S
sim_acquire "$S" chart "$T/chart.tif" 10000 '' --layout cie-tcs-frame || fail=1
sim_acquire "$S" object "$T/object.tif" 10000 '' --name obj || fail=1
sim_measure "$T/chart.cgats" || { echo "FAIL: kogei measure"; fail=1; }
[ $fail = 0 ] || exit 1

PORT=$(iiif_free_port)
A=$T/A
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$A" --no-render \
	--meta accession=TNM-E-20417 --meta "title=Tsuba with waves" --meta operator=Sato \
	--meta date=2026-12-01 --iiif-base "http://127.0.0.1:$PORT/iiif" --iiif-image-api 2 \
	--files-base "http://127.0.0.1:$PORT/files"
[ -s "$A/obj/access.tif" ] && [ -s "$A/obj/manifest.json" ] ||
	{ echo "FAIL: no access.tif or manifest.json"; cat "$T/err"; exit 1; }

if [ "$MODE" = server ]; then
	# the reference: the master through its own profile to sRGB (LittleCMS, not libvips)
	tificc -t1 -w16 -o'*sRGB' "$A/obj/master.tif" "$T/master_srgb.tif" ||
		{ echo "FAIL: tificc"; exit 1; }
	vips rawsave "$T/master_srgb.tif" "$T/master_srgb.raw" || { echo "FAIL: vips rawsave"; exit 1; }
fi
iiif_start "$A" "$PORT" "$OSD" || exit 1
if [ "$MODE" = server ]; then
	"$PY" "$here/iiif_check.py" "$A" obj "$PORT" "$T" || fail=1
	iiif_stop

	# without the bases: relative ids, said in the manifest and process.json
	B=$T/B
	expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$B" --no-render \
		--access-compression deflate
	"$PY" - "$B" <<'PY' || fail=1
import json, struct, sys
b = sys.argv[1]
m = json.load(open(b + "/obj/manifest.json"))
assert m["id"] == "manifest.json", m["id"]
assert "relative" in m["summary"]["en"][0], m["summary"]
svc = m["items"][0]["items"][0]["items"][0]["body"]["service"][0]
assert svc == {"id": "access.tif", "type": "ImageService3", "profile": "level1"}, svc
pj = json.load(open(b + "/process.json"))
o = pj["objects"][0]
assert "relative" in o["manifest"]["note"], o["manifest"]
assert o["access"]["compression"] == "deflate" and o["access"]["quality"] is None, o["access"]
with open(b + "/obj/access.tif", "rb") as f:
    d = f.read()
assert d[:4] == b"II*\0", d[:4]
(ifd,) = struct.unpack_from("<I", d, 4)
(n,) = struct.unpack_from("<H", d, ifd)
tags = {}
for i in range(n):
    tag, typ, cnt, val = struct.unpack_from("<HHII", d, ifd + 2 + 12 * i)
    tags[tag] = val & 0xFFFF if typ == 3 else val
assert tags[259] in (8, 32946), "compression %d, expected deflate" % tags[259]
print("relative ids and deflate tiles: ok")
PY
	# bad values refused, naming the option, before anything runs
	for bad in "--access-quality 0" "--access-quality 9x" "--access-compression lzw" \
		"--iiif-base ftp://x/iiif" "--iiif-base http://a/b?c" "--iiif-image-api 4"; do
		# shellcheck disable=SC2086
		expect_exit 2 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/C" $bad
		opt=${bad%% *}
		grep -q -- "$opt" "$T/err" || { echo "FAIL: '$bad': the error does not name $opt"; cat "$T/err"; fail=1; }
		[ ! -e "$T/C" ] || { echo "FAIL: '$bad' wrote $T/C"; fail=1; }
	done

	# a collection: each entry under URL/<name>, OUT/collection-manifest.json
	C=$T/col
	coll_sessions "$C" 2 || { echo "FAIL: collection sessions"; exit 1; }
	printf 'session,spectra,meta.title\ns1,chart.cgats,First\ns2,chart.cgats,Second\n' >"$C/list.csv"
	PORT=$(iiif_free_port)
	expect_exit 0 "$KOGEI" collection run "$C/list.csv" -o "$T/res" --jobs 1 \
		--iiif-base "http://127.0.0.1:$PORT/iiif" --iiif-image-api 2 \
		--files-base "http://127.0.0.1:$PORT/files"
	iiif_start "$T/res" "$PORT" || exit 1
	"$PY" - "$T/res" "$PORT" <<'PY' || fail=1
import json, os, sys, urllib.request
out, port = sys.argv[1:3]
base = "http://127.0.0.1:%s" % port
c = json.load(open(out + "/collection-manifest.json"))
assert c["@context"] == "http://iiif.io/api/presentation/3/context.json", c["@context"]
assert c["type"] == "Collection" and c["id"] == base + "/files/collection-manifest.json", c
ids = [(i["type"], i["id"], i["label"]["none"][0]) for i in c["items"]]
want = [("Manifest", base + "/files/%s/object-0001/manifest.json" % n, t)
        for n, t in (("s1", "First"), ("s2", "Second"))]
assert ids == want, (ids, want)
for n in ("s1", "s2"):
    m = json.load(open("%s/%s/object-0001/manifest.json" % (out, n)))
    svc = m["items"][0]["items"][0]["items"][0]["body"]["service"][0]
    assert svc["@id"] == base + "/iiif/%s/object-0001/access.tif" % n, svc
    info = json.load(urllib.request.urlopen(svc["@id"] + "/info.json", timeout=30))
    assert (info["width"], info["height"]) == (m["items"][0]["width"], m["items"][0]["height"]), info
    # the manifest is where its id says
    got = json.load(urllib.request.urlopen(m["id"], timeout=30))
    assert got["id"] == m["id"], got["id"]
print("collection-manifest.json: %d manifests, each served: ok" % len(ids))
PY
	iiif_stop
else
	chromium_start
	cp "$here/iiif_viewer.html" "$A/viewer.html"
	"$python" "$here/iiif_browser.py" "$devtools" \
		"http://127.0.0.1:$PORT/files/viewer.html?manifest=/files/obj/manifest.json" \
		"$T/shot" || fail=1
	[ -z "${KEEP:-}" ] || echo "screenshots: $T/shot_*.png"
fi
exit $fail
