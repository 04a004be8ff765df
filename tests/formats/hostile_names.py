#!/usr/bin/env python3
"""Hostile names through the real CLI, every written file parsed back by a real parser.

usage: hostile_names.py KOGEI READ_NAMES MAKE_REPORT_FIXTURE SOURCE_ROOT HAVE_EMBREE TMPDIR

Names made to break writers (comment terminators "--" and "-->", "]]>", markup, "&",
quotes, non-BMP characters, bidi marks, '#', CGATS words, the longest name a library
takes) go in as material names, file names, patch ids, SAMPLE_IDs and record values:

  XML   kogei export -o X.xml (Mitsuba): xmllint (libxml2) parses it; no element but
        the scene's (mitsuba_check.py); every comment, decoded by xmllint as text,
        names the materials and metals and files as they went in.
  JSON  kogei export -o X.glb: the JSON chunk through Python's json; material names
        and asset.extras as they went in; a scene file name that is not UTF-8
        refused (exit 1, nothing written).
  HTML  kogei report on a process.json holding them: Python's html.parser sees the
        same elements as for plain names and every value as one text node, a session
        path of 3000 bytes included.
  CGATS kogei measure and kogei spectra xyz: SAMPLE_IDs read back by kogei's reader.
  ENVI  kogei render --truth-labels (with Embree): class names read back by kogei's
        reader.
And the refusals: a library name with a control character, white space at its ends,
',', '|', a brace or more than 63 bytes (exit 1 naming the library and the field,
the control character not echoed, nothing written); a file name XML cannot hold."""
import json
import os
import re
import struct
import subprocess
import sys
from html.parser import HTMLParser

KOGEI, READ_NAMES, MAKE_FIXTURE, SRC, EMBREE, T = sys.argv[1:7]
failures = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL:", msg)


def run(*args, **kw):
    return subprocess.run([str(a) for a in args], capture_output=True, cwd=T, **kw)


def kogei(*args):
    return run(KOGEI, *args)


# Names a material library takes (no control characters, nothing an ENVI list or a
# list of names cannot hold): each must come back as it went in.
NAMES = [
    'x--><include filename="/etc/passwd"/><!--',
    "a--b",
    "ends-",
    "]]>",
    "<b>&amp;</b>",
    "\"double\" 'single'",
    "\U0001F375 tea \u6f06",
    "\u200fRTL\u202e override",
    "# not a comment",
    "END_DATA",
    "x" * 63,
    "semi; \\back\\ slash",
    "\u2028 separator",
    "-->",
    "a'b\"c<d>e&f",
    "---",
]
NK = [{"model": "vial-laroche2008-dcp", "element": "Au"},
      {"model": "vial-laroche2008-dcp", "element": "Ag"},
      {"model": "vial2008ch-dcp", "element": "Cu"}]
SURFACE = {"roughness": 0.1, "mirror_width": 0.02, "gloss": 0.8, "mirror": 0.2}


def metal(name, i):
    return dict({"name": name, "kind": "metal", "nk": NK[i % 3]}, **SURFACE)


def alloy(name, parts):
    comps = [{"material": m, "fraction": f} for m, f in parts]
    return dict({"name": name, "kind": "alloy", "components": comps}, **SURFACE)


def write_json(name, obj):
    with open(os.path.join(T, name), "w", encoding="utf-8") as f:
        json.dump(obj, f, ensure_ascii=False)


# 12 metals and 4 alloys of them (an alloy's metals after its first are named in
# comments), in groups of four for the tsuba's four face ids; the last group, with
# plain file names, is the reported one: a metal named to close the comment and open
# an <include>.
METALS = NAMES[:12]
ALLOYS = [(NAMES[12], [(NAMES[2], 0.2), (NAMES[1], 0.8)]),
          (NAMES[13], [(NAMES[5], 0.6), (NAMES[6], 0.4)]),
          (NAMES[14], [(NAMES[3], 0.9), (NAMES[0], 0.1)]),
          (NAMES[15], [(NAMES[10], 0.5), (NAMES[11], 0.3), (NAMES[4], 0.2)])]
GROUPS = [NAMES[0:4], NAMES[4:8], NAMES[8:12], [NAMES[12], NAMES[13], NAMES[15], NAMES[8]],
          [NAMES[14], NAMES[9], NAMES[7], NAMES[3]]]
FILES = [("scene 0.json", "out 0 --&<'\">]]>#.xml"),
         ("scene 1 --><x>&'\"#.json", "out 1 ]]>.xml"),
         ("scene 2 ]]>.json", "out 2 &amp;.xml"),
         ("scene 3 --.json", "out 3 <!--.xml"),
         ("scene 4.json", "out 4.xml")]
LIB = "lib --><&'\"#.json"
LIBRARY = {"format": "kogei-materials/1",
           "materials": [metal(n, i) for i, n in enumerate(METALS)] +
                        [alloy(n, p) for n, p in ALLOYS]}
write_json(LIB, LIBRARY)
KIND = {n: "metal" for n in METALS}
KIND.update({n: "alloy" for n, _ in ALLOYS})
PARTS = {n: [m for m, _ in p] for n, p in ALLOYS}


def scene(path, names, library=LIB):
    write_json(path, {
        "format": "kogei-scene/1",
        "mesh": {"generator": "tsuba", "segments": 16},
        "materials": {"library": library,
                      "face_ids": {str(i): n for i, n in enumerate(names)}},
        "light": {"illuminant": "D65", "direction": [-0.6, -1, 1.6], "intensity": 1.2},
        "camera": {"position": [0, -2.2, 1.85], "look_at": [0, 0, -0.05], "fov_deg": 36,
                   "width": 24, "height": 18},
        "sampling": {"spp": 1, "wavelengths": 1, "bounces": 2, "seed": 1}})


def xml_text(raw):
    """What an XML parser (xmllint) reads from raw as character data."""
    r = run("xmllint", "--xpath", "string(/c)", "-", input=("<c>%s</c>" % raw).encode())
    check(r.returncode == 0, "xmllint cannot read %r as text: %s" % (raw, r.stderr[-300:]))
    out = r.stdout.decode("utf-8")
    return out[:-1] if out.endswith("\n") else out   # the line end xmllint adds


def comments(xml_path):
    r = run("xmllint", "--xpath", "//comment()", xml_path)
    check(r.returncode == 0, "xmllint --xpath //comment(): %s" % r.stderr[-300:])
    return [xml_text(c) for c in re.findall(r"<!--(.*?)-->", r.stdout.decode("utf-8"), re.S)]


def check_mitsuba(names, scene_file, xml):
    r = kogei("export", "--scene", scene_file, "-o", xml)
    check(r.returncode == 0, "export %s: exit %d: %s" % (xml, r.returncode, r.stderr[-400:]))
    if r.returncode:
        return
    path = os.path.join(T, xml)
    lint = run("xmllint", "--noout", path)
    check(lint.returncode == 0, "%s is not well-formed XML (xmllint): %s"
          % (xml, lint.stderr.decode(errors="replace")[-600:]))
    if lint.returncode:
        return
    inc = run("xmllint", "--xpath", "count(//include)", path)
    check(inc.stdout.strip() == b"0", "%s: %s <include> elements" % (xml, inc.stdout.strip()))
    st = run(sys.executable, os.path.join(SRC, "tests/render/mitsuba_check.py"), path)
    check(st.returncode == 0, "%s: %s" % (xml, (st.stdout + st.stderr).decode()[-400:]))
    got = comments(path)
    head = got[0] if got else ""
    check("from the scene %s (kogei-scene/1)" % scene_file in head and
          "scalar_spectral %s\n" % xml in head,
          "%s: the first comment does not name the files as they are: %r" % (xml, head))
    for n in names:
        check(" %s (%s) " % (n, KIND[n]) in got,
              "%s: no comment reads ' %s (%s) ' (comments: %r)" % (xml, n, KIND[n], got[:6]))
        for m in PARTS.get(n, [])[1:]:
            check(any(c.startswith(" %s: fraction " % m) for c in got),
                  "%s: alloy %r: no comment names its metal %r" % (xml, n, m))


def glb_json(path):
    with open(path, "rb") as f:
        b = f.read()
    n, kind = struct.unpack("<I4s", b[12:20])
    check(kind == b"JSON", "%s: first chunk %r" % (path, kind))
    return json.loads(b[20:20 + n].decode("utf-8"))


def check_gltf(k, names, scene_file):
    glb = "obj %d --&<'\">.glb" % k
    r = kogei("export", "--scene", scene_file, "-o", glb)
    check(r.returncode == 0, "export %s: exit %d: %s" % (glb, r.returncode, r.stderr[-400:]))
    if r.returncode:
        return
    j = glb_json(os.path.join(T, glb))
    mats = {m["name"]: m for m in j.get("materials", [])}
    for n in names:
        check(n in mats and mats[n]["extras"]["kogei_material"] == n,
              "%s: material %r not named as it went in (%r)" % (glb, n, sorted(mats)))
    extras = j.get("asset", {}).get("extras", {}).get("kogei", {})
    check(extras.get("scene") == scene_file and extras.get("library", "").endswith("/" + LIB),
          "%s: asset.extras.kogei %r" % (glb, extras))


def check_export_refusals():
    bad = os.fsdecode(b"scene \xe9t\xe9.json")   # Latin-1: not UTF-8
    scene(bad, GROUPS[0])
    r = kogei("export", "--scene", bad, "-o", "latin1.glb")
    check(r.returncode == 1 and b"not UTF-8" in r.stderr and b"latin1.glb" in r.stderr and
          not os.path.exists(os.path.join(T, "latin1.glb")),
          "a scene file name that is not UTF-8 into glTF: exit %d, %r"
          % (r.returncode, r.stderr[-300:]))
    ctl = "scene \x01.json"
    scene(ctl, GROUPS[0])
    r = kogei("export", "--scene", ctl, "-o", "ctl.xml")
    check(r.returncode == 1 and b"U+0001" in r.stderr and b"XML" in r.stderr and
          not os.path.exists(os.path.join(T, "ctl.xml")) and
          not os.path.exists(os.path.join(T, "ctl")),
          "a scene file name XML cannot hold: exit %d, %r" % (r.returncode, r.stderr[-300:]))


REFUSED_NAMES = ["tab\there", "line\nfeed", "cr\rhere", "esc\x1b[31mred", "c1\u0085x",
                 " lead", "trail ", "comma, name", "bar|name", "{brace", "brace}", "y" * 64]


def check_library_refusals():
    for i, bad in enumerate(REFUSED_NAMES):
        lib = "bad%d.json" % i
        write_json(lib, {"format": "kogei-materials/1",
                         "materials": [metal("gold", 0), metal(bad, 1)]})
        scene("bad%d_scene.json" % i, ["gold", bad, "gold", "gold"], lib)
        out = "bad%d.xml" % i
        r = kogei("export", "--scene", "bad%d_scene.json" % i, "-o", out)
        err = r.stderr[:-1] if r.stderr.endswith(b"\n") else r.stderr
        ctl = [c for c in bad if ord(c) < 0x20 or 0x7F <= ord(c) <= 0x9F]
        check(r.returncode == 1 and lib.encode() in err and b"field name" in err and
              not any(c.encode() in err for c in ctl) and
              not os.path.exists(os.path.join(T, out)),
              "library name %r: exit %d, %r" % (bad, r.returncode, err[-300:]))


def check_cgats():
    ids = ["#x", "a b", "x--><y>&amp;", "tab\there", "\U0001F375\u202e", "trail ", " lead",
           "it's", "END_DATA", "KEYWORD", "{b}", "z" * 31]
    bands = list(range(400, 705, 5))
    with open(os.path.join(T, "spectra.cgats"), "w", encoding="utf-8") as f:
        f.write("CGATS.17\nORIGINATOR \"test\"\nNUMBER_OF_FIELDS %d\nBEGIN_DATA_FORMAT\n"
                "SAMPLE_ID %s\nEND_DATA_FORMAT\nNUMBER_OF_SETS %d\nBEGIN_DATA\n"
                % (len(bands) + 1, " ".join("SPEC_%d" % b for b in bands), len(ids)))
        for i, s in enumerate(ids):
            f.write("\"%s\" %s\n" % (s, " ".join("%.3f" % (0.2 + 0.05 * i) for _ in bands)))
        f.write("END_DATA\n")
    layout = json.load(open(os.path.join(SRC, "fixtures/demo/cie-tcs-frame.json")))
    layout["patches"] = layout["patches"][:len(ids)]
    for p, s in zip(layout["patches"], ids):
        p["id"] = s
        p.pop("alias", None)
    write_json("ids --><&.json", layout)
    r = kogei("measure", "--spectro", "sim:spectra.cgats", "--chart", "ids --><&.json",
              "--yes", "-o", "measured #1.cgats")
    check(r.returncode == 0, "measure: exit %d: %s" % (r.returncode, r.stderr[-400:]))
    r2 = kogei("spectra", "xyz", "measured #1.cgats", "-o", "xyz.cgats")
    check(r2.returncode == 0, "spectra xyz: exit %d: %s" % (r2.returncode, r2.stderr[-400:]))
    for out in ("measured #1.cgats", "xyz.cgats"):
        rb = run(READ_NAMES, "cgats", out)
        check(rb.returncode == 0, "read_names %s: %s" % (out, rb.stderr))
        if rb.returncode:
            continue
        t = json.loads(rb.stdout)
        got = [row[t["fields"].index("SAMPLE_ID")] for row in t["sets"]]
        check(got == ids, "%s: SAMPLE_IDs read back %r, written %r" % (out, got, ids))


def check_envi():
    if EMBREE != "1":
        print("ENVI: skipped (kogei render needs Embree)")
        return
    r = kogei("render", "--scene", "scene 0.json", "-o", "truth.png", "--truth-labels",
              "truth --><&.hdr", "--quiet")
    check(r.returncode == 0, "render --truth-labels: exit %d: %s" % (r.returncode,
                                                                     r.stderr[-400:]))
    rb = run(READ_NAMES, "envi", "truth --><&.hdr")
    check(rb.returncode == 0, "read_names envi: %s" % rb.stderr)
    if rb.returncode == 0:
        got = json.loads(rb.stdout)["class_names"]
        want = ["background"] + [m["name"] for m in LIBRARY["materials"]]
        check(got == want, "ENVI class names read back %r, written %r" % (got, want))


class Page(HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.tags, self.texts = set(), []

    def handle_starttag(self, tag, attrs):
        self.tags.add(tag)

    def handle_data(self, data):
        self.texts.append(data)


def report(outdir):
    r = kogei("report", outdir)
    check(r.returncode == 0, "report %s: exit %d: %s" % (outdir, r.returncode, r.stderr[-400:]))
    p = Page()
    with open(os.path.join(T, outdir, "report.html"), encoding="utf-8", errors="replace") as f:
        p.feed(f.read())
    p.close()
    return p


def check_html():
    for d in ("plain", "hostile"):
        r = run(MAKE_FIXTURE, d)
        check(r.returncode == 0, "make_report_fixture: %s" % r.stderr)
    base = report("plain")
    pj = os.path.join(T, "hostile", "process.json")
    doc = json.load(open(pj, encoding="utf-8"))
    values = {"accession": NAMES[0], "title": NAMES[4], "notes": NAMES[5],
              "x.custom": NAMES[6], "operator": "ends-- &#39; &amp; ]]>"}
    doc["meta"] = values
    patches = doc["calibration"]["patches"]
    for p, n in zip(patches, NAMES):
        p["name"] = n
    for c, n in zip(doc["objects"][0]["classes"], NAMES[8:]):
        c["name"] = n
    long_path = "/data/" + "\u6f06\U0001F375-" * 375   # 3006 bytes of UTF-8
    doc["session"]["path"] = long_path
    doc["warnings"].append(NAMES[0])
    with open(pj, "w", encoding="utf-8") as f:
        json.dump(doc, f, ensure_ascii=False)
    page = report("hostile")
    check(page.tags == base.tags, "elements that no plain report has: %s, missing %s"
          % (sorted(page.tags - base.tags), sorted(base.tags - page.tags)))
    texts = set(page.texts)
    for k, v in values.items():
        check(v in texts, "record %s: %r is no text node of the page" % (k, v))
    for n in NAMES[:len(patches)]:
        check(n in texts, "patch name %r is no text node of the page" % n)
    for c in doc["objects"][0]["classes"]:
        check(c["name"] in texts, "class %r is no text node of the page" % c["name"])
    check(NAMES[0] in texts, "the warning %r is no text node" % NAMES[0])
    sub = [t for t in page.texts if t.startswith("Session ")]
    check(sub and sub[0].startswith("Session %s, processed " % long_path),
          "the session line cut or changed: %d of %d bytes"
          % (len(sub[0].encode()) if sub else 0, len(long_path.encode())))


def main():
    for k, (names, (scene_file, xml)) in enumerate(zip(GROUPS, FILES)):
        scene(scene_file, names)
        check_mitsuba(names, scene_file, xml)
        check_gltf(k, names, scene_file)
    check_export_refusals()
    check_library_refusals()
    check_cgats()
    check_envi()
    check_html()
    if failures:
        print("%d check(s) failed" % len(failures))
        return 1
    print("PASS: hostile names through XML, JSON, HTML, CGATS and ENVI")
    return 0


if __name__ == "__main__":
    sys.exit(main())
