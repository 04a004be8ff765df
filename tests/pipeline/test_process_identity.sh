#!/bin/sh
# Each object's identity in its own files: a session with two objects whose records
# differ in every field (accession, title, operator, date, rights), processed with a
# run-level --meta; each object's master.tif (TIFF tags and the XMP packet of tag 700,
# read by a TIFF parser of this test and by Debian's exiftool, whose -validate finds no
# fault), cube.hdr's description, labels.json, object.glb (asset.extras, asset.copyright;
# the Khronos validator when installed) and process.json carry its own record (the
# run's --meta under the capture's) and none of the other object's values. A changed
# run --meta re-writes the files; an unchanged run keeps them.
# usage: test_process_identity.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
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
cd "$T" || exit 1
EXIFTOOL=$(command -v exiftool || true)

# Records that differ in every field; characters XML, ENVI and JSON must escape.
sim_scenes . chart_truth.cgats &&
sim_acquire S dark chart.tif 10000 '&light=0' &&
sim_acquire S flat chart.tif 10000 '&uniform=0.6' &&
sim_acquire S chart chart.tif 10000 '' --layout cie-tcs-frame &&
sim_acquire S object object.tif 10000 '' --meta accession=1987.12.3 \
	--meta 'title=<b>Bowl</b> & "lid" – 漆' --meta 'operator=Aiko Sato' \
	--meta 'date=c. 1650 (Edo)' --meta 'rights=© Museum A 2026 ?> ]]>' &&
sim_acquire S object object.tif 10000 '' --meta accession=2001.5.77 \
	--meta 'title=Jar {restored} \ 壺' --meta "operator=Ben O'Ito" \
	--meta date=2001-05-07 --meta 'rights=CC BY 4.0 Ito' &&
sim_measure chart.cgats || { echo "FAIL: setting up the session"; exit 1; }

"$KOGEI" process S --spectra chart.cgats -o out --no-render --meta 'notes=run note -->' \
	--meta 'operator=Run Operator' >process.log 2>&1 ||
	{ cat process.log; echo "FAIL: process"; exit 1; }

# check.py OUT NOTES EXIFTOOL VALIDATOR: every file of every object against its record
cat >check.py <<'PYEOF'
import json, os, struct, subprocess, sys
import xml.etree.ElementTree as ET
out, notes, exiftool, validator, layout_file = sys.argv[1:6]
ok = True
def check(cond, msg):
    global ok
    if not cond:
        print("FAIL:", msg); ok = False
own = {
    "object-0001": {"accession": "1987.12.3", "title": '<b>Bowl</b> & "lid" – 漆',
                    "operator": "Aiko Sato", "date": "c. 1650 (Edo)",
                    "rights": "© Museum A 2026 ?> ]]>"},
    "object-0002": {"accession": "2001.5.77", "title": "Jar {restored} \\ 壺",
                    "operator": "Ben O'Ito", "date": "2001-05-07",
                    "rights": "CC BY 4.0 Ito"},
}
for r in own.values():
    r["notes"] = notes  # the run's --meta under the capture's: operator is the object's
pj = json.load(open(os.path.join(out, "process.json")))
session_id = json.load(open("S/session.json")).get("id")
objs = {o["capture"]: o for o in pj["objects"]}
check(sorted(objs) == sorted(own), "objects %r" % sorted(objs))

def xml_escaped(s):
    return (s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
             .replace('"', "&quot;").replace("'", "&apos;"))

def tiff_tags(path):
    """IFD0 of a little- or big-endian TIFF: {tag: bytes or numbers}."""
    d = open(path, "rb").read()
    e = "<" if d[:2] == b"II" else ">"
    (ifd,) = struct.unpack(e + "I", d[4:8])
    (n,) = struct.unpack(e + "H", d[ifd:ifd + 2])
    sizes = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 7: 1}
    tags = {}
    for i in range(n):
        tag, typ, cnt = struct.unpack(e + "HHI", d[ifd + 2 + 12 * i:ifd + 10 + 12 * i])
        size = sizes.get(typ, 1) * cnt
        at = ifd + 10 + 12 * i
        if size > 4:
            (at,) = struct.unpack(e + "I", d[at:at + 4])
        raw = d[at:at + size]
        if typ == 3:
            tags[tag] = struct.unpack(e + "%dH" % cnt, raw)
        elif typ == 5:
            v = struct.unpack(e + "%dI" % (2 * cnt), raw)
            tags[tag] = [v[2 * k] / v[2 * k + 1] for k in range(cnt)]
        else:
            tags[tag] = raw
    return tags, d

def cgats_rows(path):
    lines = open(path).read().splitlines()
    fields = lines[lines.index("BEGIN_DATA_FORMAT") + 1].split()
    start, end = lines.index("BEGIN_DATA"), lines.index("END_DATA")
    return [dict(zip(fields, l.split())) for l in lines[start + 1:end]]
layout = json.load(open(layout_file))
at_mm = {p["id"]: tuple(p["center_mm"]) for p in layout["patches"]}
at_px = {r["SAMPLE_ID"].strip('"'): (float(r["PIXEL_X"]), float(r["PIXEL_Y"]))
         for r in cgats_rows("chart_truth.cgats")}
a = layout["chart_area_mm"]
cx, cy = a[0] + a[2] / 2, a[1] + a[3] / 2
by_mm = {v: k for k, v in at_mm.items()}
px = lambda x, y: at_px[by_mm[(x, y)]]
pitch = 45.0
(x0, y0), (x1, y1) = px(cx - pitch, cy), px(cx + pitch, cy)
(u0, v0), (u1, v1) = px(cx, cy - pitch), px(cx, cy + pitch)
truth_ppmm = abs((x1 - x0) * (v1 - v0) - (u1 - u0) * (y1 - y0)) ** 0.5 / (2 * pitch)

NS = {"x": "adobe:ns:meta/", "rdf": "http://www.w3.org/1999/02/22-rdf-syntax-ns#",
      "dc": "http://purl.org/dc/elements/1.1/", "xmp": "http://ns.adobe.com/xap/1.0/",
      "kogei": "urn:kogei:xmp:1.0:"}

for name, rec in own.items():
    other = [v for k, v in own[[n for n in own if n != name][0]].items() if k != "notes"]
    o = objs.get(name, {})
    ident = o.get("identity") or {}
    check(ident.get("record") == rec, "%s: process.json identity.record %r" %
          (name, ident.get("record")))
    check(ident.get("object") == name and ident.get("session") == "S" and
          ident.get("session_id") == session_id,
          "%s: process.json identity names %r" % (name, ident))
    col = ident.get("colour_accuracy") or {}
    check(col.get("basis") == "leave-one-out" and col.get("patches", 0) > 3 and
          0 < col.get("de00_mean", -1) <= col.get("de00_max", -1),
          "%s: held-out colour accuracy %r" % (name, col))
    # pixels per mm against the simulation's truth: the patch centres about the
    # chart's centre (45 mm apart in the layout) where the simulation put them
    ppmm = ident.get("pixels_per_mm")
    check(isinstance(ppmm, float) and abs(ppmm - truth_ppmm) < 0.01 * truth_ppmm,
          "%s: pixels_per_mm %r, the simulation's %.4f (%s)" %
          (name, ppmm, truth_ppmm, ident.get("pixels_per_mm_source")))
    print("ok: %s: %.4f pixels per mm, the simulation's %.4f" % (name, ppmm or 0, truth_ppmm))
    d = os.path.join(out, name)

    # cube.hdr: the description's "key: value" lines, values JSON
    hdr = open(os.path.join(d, "cube.hdr"), encoding="utf-8").read()
    start = hdr.index("description = {") + len("description = {")
    desc = hdr[start:hdr.index("}", start)]
    fields = {}
    for line in desc.split("\n")[1:]:
        k, _, v = line.partition(": ")
        fields[k] = json.loads(v)
    got = {k[7:]: v for k, v in fields.items() if k.startswith("record.")}
    check(got == rec, "%s: cube.hdr record %r" % (name, got))
    check(fields.get("object") == name and fields.get("session") == "S",
          "%s: cube.hdr names %r" % (name, fields))
    check(abs(fields.get("colour_accuracy.de00_mean", -9) - col.get("de00_mean", 9)) < 1e-3,
          "%s: cube.hdr held-out mean %r" % (name, fields.get("colour_accuracy.de00_mean")))
    for v in other:
        check(v not in hdr and json.dumps(v, ensure_ascii=False)[1:-1] not in hdr,
              "%s: cube.hdr holds the other object's %r" % (name, v))

    # labels.json
    lj = json.load(open(os.path.join(d, "labels.json"), encoding="utf-8"))
    check((lj.get("identity") or {}).get("record") == rec,
          "%s: labels.json identity %r" % (name, lj.get("identity")))
    text = open(os.path.join(d, "labels.json"), encoding="utf-8").read()
    for v in other:
        check(json.dumps(v, ensure_ascii=False)[1:-1] not in text and
              json.dumps(v)[1:-1] not in text,
              "%s: labels.json holds the other object's %r" % (name, v))

    # object.glb: the JSON chunk
    g = open(os.path.join(d, "object.glb"), "rb").read()
    magic, version, length = struct.unpack("<4sII", g[:12])
    clen, ctype = struct.unpack("<I4s", g[12:20])
    check(magic == b"glTF" and version == 2 and ctype == b"JSON", "%s: glb header" % name)
    gj = json.loads(g[20:20 + clen].decode("utf-8"))
    asset = gj.get("asset", {})
    gi = asset.get("extras", {}).get("kogei", {}).get("identity") or {}
    check(gi.get("record") == rec and gi.get("object") == name,
          "%s: glb asset.extras.kogei.identity %r" % (name, gi))
    check(asset.get("copyright") == rec["rights"],
          "%s: glb asset.copyright %r" % (name, asset.get("copyright")))
    chunk = g[20:20 + clen].decode("utf-8")
    for v in other:
        check(json.dumps(v, ensure_ascii=False)[1:-1] not in chunk and
              json.dumps(v)[1:-1] not in chunk,
              "%s: object.glb holds the other object's %r" % (name, v))
    if validator:
        r = subprocess.run(["node", validator.split("|")[0], validator.split("|")[1],
                            os.path.join(d, "object.glb")], capture_output=True, text=True)
        check(r.returncode == 0, "%s: glTF validator: %s%s" % (name, r.stdout, r.stderr))

    # master.tif: the tags as this parser reads them, the XMP packet parsed
    tif = os.path.join(d, "master.tif")
    if not (o.get("master") and os.path.exists(tif)):
        print("note: no master.tif (built without LittleCMS?): its checks left out")
        continue
    tags, data = tiff_tags(tif)
    ascii_ = lambda t: tags.get(t, b"").rstrip(b"\0").decode("utf-8", "replace")
    check(ascii_(270) == rec["title"], "%s: ImageDescription %r" % (name, ascii_(270)))
    check(ascii_(315) == rec["operator"], "%s: Artist %r" % (name, ascii_(315)))
    check(ascii_(33432) == rec["rights"], "%s: Copyright %r" % (name, ascii_(33432)))
    started = [c for c in json.load(open("S/session.json"))["captures"]
               if c["name"] == name][0]["started"]
    check(ascii_(306) == started[:19].replace("-", ":").replace("T", " "),
          "%s: DateTime %r, capture started %s" % (name, ascii_(306), started))
    check(tags.get(296) == (2,) and abs(tags[282][0] - 25.4 * ppmm) < 0.01 and
          tags[283] == tags[282], "%s: resolution %r %r %r for %r px/mm" %
          (name, tags.get(282), tags.get(283), tags.get(296), ppmm))
    xmp = tags.get(700, b"")
    check(xmp.startswith(b'<?xpacket begin="\xef\xbb\xbf" id="W5M0MpCehiHzreSzNTczkc9d"?>')
          and xmp.rstrip().endswith(b'<?xpacket end="w"?>'), "%s: xpacket wrapper" % name)
    try:
        root = ET.fromstring(xmp)  # the processing instructions are skipped
    except ET.ParseError as e:
        check(False, "%s: XMP not well-formed: %s" % (name, e)); continue
    desc = root.find("rdf:RDF/rdf:Description", NS)
    val = lambda path: [e.text for e in desc.findall(path, NS)]
    check(val("dc:identifier") == [rec["accession"]], "%s: dc:identifier" % name)
    check(val("dc:title/rdf:Alt/rdf:li") == [rec["title"]], "%s: dc:title %r" %
          (name, val("dc:title/rdf:Alt/rdf:li")))
    check(val("dc:creator/rdf:Seq/rdf:li") == [rec["operator"]], "%s: dc:creator" % name)
    # dc:date only where the record's date is an XMP date; always in kogei:Record
    iso = rec["date"][:1].isdigit()
    check(val("dc:date/rdf:Seq/rdf:li") == ([rec["date"]] if iso else []),
          "%s: dc:date %r" % (name, val("dc:date/rdf:Seq/rdf:li")))
    check(val("dc:rights/rdf:Alt/rdf:li") == [rec["rights"]], "%s: dc:rights" % name)
    check(val("kogei:Object") == [name] and val("kogei:Session") == ["S"] and
          val("kogei:SessionID") == [session_id], "%s: kogei names" % name)
    check(abs(float(val("kogei:HeldOutDE00Mean")[0]) - col["de00_mean"]) < 1e-3,
          "%s: kogei:HeldOutDE00Mean %r" % (name, val("kogei:HeldOutDE00Mean")))
    pairs = dict(zip(val("kogei:Record/rdf:Bag/rdf:li/kogei:Key"),
                     val("kogei:Record/rdf:Bag/rdf:li/kogei:Value")))
    check(pairs == rec, "%s: kogei:Record %r" % (name, pairs))
    for v in other:
        check(v.encode() not in data and xml_escaped(v).encode() not in data,
              "%s: master.tif holds the other object's %r" % (name, v))

    if not exiftool:
        continue
    # Debian's exiftool: every field read back, -validate finds nothing
    r = subprocess.run([exiftool, "-j", "-a", "-G1", "-struct", tif], capture_output=True)
    ex = json.loads(r.stdout.decode("utf-8"))[0]
    want = {"XMP-dc:Identifier": rec["accession"], "XMP-dc:Title": rec["title"],
            "XMP-dc:Creator": rec["operator"], "XMP-dc:Rights": rec["rights"],
            "XMP-dc:Description": rec["title"], "IFD0:ImageDescription": rec["title"],
            "IFD0:Artist": rec["operator"], "IFD0:Copyright": rec["rights"],
            "XMP-kogei:Object": name, "XMP-kogei:Session": "S",
            "XMP-kogei:SessionID": session_id, "IFD0:ResolutionUnit": "inches"}
    for k, v in want.items():
        got = ex.get(k)
        got = got[0] if isinstance(got, list) and len(got) == 1 else got
        check(str(got) == v, "%s: exiftool %s %r, expected %r" % (name, k, got, v))
    # dc:date is an XMP date where it is one (exiftool shows it with colons)
    date = ex.get("XMP-dc:Date")
    date = date[0] if isinstance(date, list) and len(date) == 1 else date
    check((str(date).replace(":", "-") == rec["date"]) if iso else date is None,
          "%s: exiftool XMP-dc:Date %r" % (name, date))
    check(abs(float(ex.get("IFD0:XResolution", 0)) - 25.4 * ppmm) < 0.01,
          "%s: exiftool XResolution %r" % (name, ex.get("IFD0:XResolution")))
    check(abs(float(ex.get("XMP-kogei:HeldOutDE00Mean", -9)) - col["de00_mean"]) < 1e-3,
          "%s: exiftool HeldOutDE00Mean %r" % (name, ex.get("XMP-kogei:HeldOutDE00Mean")))
    recs = ex.get("XMP-kogei:Record") or []
    check({e.get("Key"): str(e.get("Value")) for e in recs} == rec,
          "%s: exiftool XMP-kogei:Record %r" % (name, recs))
    dump = r.stdout.decode("utf-8")
    for v in other:
        check(json.dumps(v, ensure_ascii=False)[1:-1] not in dump,
              "%s: exiftool reads the other object's %r" % (name, v))
    r = subprocess.run([exiftool, "-validate", "-warning", "-a", tif], capture_output=True,
                       text=True)
    lines = [l for l in r.stdout.splitlines() if l.strip()]
    check(lines and lines[0].split(":", 1)[1].strip() == "OK" and
          not any(l.startswith("Warning") for l in lines) and "Missing required" not in r.stdout,
          "%s: exiftool -validate -warning -a: %s" % (name, r.stdout + r.stderr))
    print("ok: %s: exiftool %s" % (name, " | ".join(lines)))
sys.exit(0 if ok else 1)
PYEOF

LAYOUT=$FIX/demo/cie-tcs-frame.json
VALIDATOR=
if command -v node >/dev/null 2>&1 &&
	[ -f "$ROOT/.tools/gltf-validator/node_modules/gltf-validator/package.json" ]; then
	VALIDATOR="$ROOT/tests/gltf_validate.mjs|$ROOT/.tools/gltf-validator"
else
	echo "note: no node or gltf-validator (scripts/setup.sh): object.glb checked by its JSON only"
fi
"$PY" check.py out 'run note -->' "$EXIFTOOL" "$VALIDATOR" "$LAYOUT" || fail=1

# An unchanged run keeps the objects; a changed run --meta re-writes their files.
"$KOGEI" process S --spectra chart.cgats -o out --no-render --meta 'notes=run note -->' \
	--meta 'operator=Run Operator' >process2.log 2>&1 ||
	{ cat process2.log; echo "FAIL: process again"; exit 1; }
grep -q "2 unchanged" process2.log ||
	{ echo "FAIL: an unchanged run re-wrote the objects:"; tail -1 process2.log; fail=1; }
"$KOGEI" process S --spectra chart.cgats -o out --no-render --meta 'notes=second note' \
	--meta 'operator=Run Operator' >process3.log 2>&1 ||
	{ cat process3.log; echo "FAIL: process with another --meta"; exit 1; }
grep -q "2 processed, 0 unchanged" process3.log ||
	{ echo "FAIL: a changed --meta kept the objects' files:"; tail -1 process3.log; fail=1; }
"$PY" check.py out 'second note' "$EXIFTOOL" "" "$LAYOUT" || fail=1

[ $fail = 0 ] || exit 1
[ -n "$EXIFTOOL" ] || kg_skip "exiftool missing (package libimage-exiftool-perl): every other file was checked"
echo "PASS: process-identity"
