#!/usr/bin/env python3
"""Structural check of a Mitsuba 3 scene written by kogei (kg_scene_write_mitsuba).

No Mitsuba can be installed here, so the XML is checked against Mitsuba 3's own plugin
reference: the plugin types and parameter names below are copied from the
``pluginparameters`` tables in the sources of mitsuba-renderer/mitsuba3 (commit
b45b0a930275114de0f8c34e8cf52775e176ca9a, 2026-08-08): src/bsdfs/conductor.cpp,
roughconductor.cpp, roughplastic.cpp, diffuse.cpp, blendbsdf.cpp, twosided.cpp;
src/shapes/ply.cpp; src/sensors/perspective.cpp; src/emitters/directional.cpp,
constant.cpp; src/integrators/path.cpp; src/films/hdrfilm.cpp;
src/samplers/independent.cpp; src/rfilters/box.cpp; the XML syntax (scene version,
<spectrum value="wavelength:value, ...">, <lookat origin target up>) from
docs/src/key_topics/scene_format.rst.

usage: mitsuba_check.py SCENE.xml [--scene SCENE.json] [--model-csv NAME=TABLE.csv ...]
Checks: the file parses; every plugin is of a known type and every parameter is one
of that plugin's, with a value of the documented kind; ids are unique and every <ref>
names one; every file named exists (PLY headers read: binary, triangles only, vertex
count > 0); the material spectra are on 360, 400..700 in 5 nm steps, 830 nm and the
light spectra on 400..700 nm in 5 nm steps (61 values), strictly increasing in
wavelength, finite, n > 0, k >= 0; blend weights in [0, 1]; with --scene, the camera
and the light direction are the scene's; with --model-csv, the normal-incidence
Fresnel reflectance of each metal's eta, k equals kogei model's 0-degree column.
Prints a summary; exits 1 on the first failure."""
import json
import math
import os
import sys
import xml.etree.ElementTree as ET

# plugin kind -> type -> {parameter name: allowed property tags}
SPEC = ("spectrum", "rgb", "float", "texture")
ALLOWED = {
    "bsdf": {
        "conductor": {"material": ("string",), "eta": SPEC, "k": SPEC,
                      "specular_reflectance": SPEC},
        "roughconductor": {"material": ("string",), "eta": SPEC, "k": SPEC,
                           "specular_reflectance": SPEC, "distribution": ("string",),
                           "alpha": ("float", "texture"), "alpha_u": ("float", "texture"),
                           "alpha_v": ("float", "texture"), "sample_visible": ("boolean",)},
        "roughplastic": {"diffuse_reflectance": SPEC, "nonlinear": ("boolean",),
                         "int_ior": ("float", "string"), "ext_ior": ("float", "string"),
                         "specular_reflectance": SPEC, "distribution": ("string",),
                         "alpha": ("float",), "sample_visible": ("boolean",)},
        "diffuse": {"reflectance": SPEC},
        "blendbsdf": {"weight": ("float", "texture")},
        "twosided": {},
    },
    "shape": {"ply": {"filename": ("string",), "face_normals": ("boolean",),
                      "flip_tex_coords": ("boolean",), "flip_normals": ("boolean",),
                      "to_world": ("transform",)}},
    "sensor": {"perspective": {"to_world": ("transform",), "fov": ("float",),
                               "focal_length": ("string",), "fov_axis": ("string",),
                               "near_clip": ("float",), "far_clip": ("float",),
                               "principal_point_offset_x": ("float",),
                               "principal_point_offset_y": ("float",), "srf": ("spectrum",)}},
    "emitter": {"directional": {"irradiance": ("spectrum", "rgb"), "to_world": ("transform",),
                                "direction": ("vector",)},
                "constant": {"radiance": ("spectrum", "rgb")}},
    "integrator": {"path": {"max_depth": ("integer",), "rr_depth": ("integer",),
                            "hide_emitters": ("boolean",)}},
    "film": {"hdrfilm": {"width": ("integer",), "height": ("integer",),
                         "file_format": ("string",), "pixel_format": ("string",),
                         "component_format": ("string",), "crop_offset_x": ("integer",),
                         "crop_offset_y": ("integer",), "crop_width": ("integer",),
                         "crop_height": ("integer",), "sample_border": ("boolean",)}},
    "sampler": {"independent": {"sample_count": ("integer",), "seed": ("integer",)}},
    "rfilter": {"box": {}},
}
# nested plugins each kind may hold (scene: anything)
NESTED = {"bsdf": {"bsdf"}, "sensor": {"sampler", "film"}, "film": {"rfilter"},
          "shape": {"bsdf"}, "emitter": set(), "integrator": set(), "sampler": set(),
          "rfilter": set()}
PROPERTY_TAGS = {"string", "float", "integer", "boolean", "spectrum", "rgb", "vector",
                 "point", "transform", "texture"}
CHOICES = {("roughconductor", "distribution"): {"beckmann", "ggx"},
           ("roughplastic", "distribution"): {"beckmann", "ggx"},
           ("perspective", "fov_axis"): {"x", "y", "diagonal", "smaller", "larger"}}
MATERIAL_GRID = [360.0] + [400.0 + 5 * i for i in range(61)] + [830.0]
LIGHT_GRID = [400.0 + 5 * i for i in range(61)]


class Fail(Exception):
    pass


def need(cond, msg):
    if not cond:
        raise Fail(msg)


def spectrum(el):
    """wavelength:value pairs of a <spectrum value=...>, or a constant."""
    text = el.get("value")
    need(text is not None, "<spectrum name=%r> without value" % el.get("name"))
    if ":" not in text:
        v = float(text)
        need(math.isfinite(v), "spectrum %r: %r" % (el.get("name"), text))
        return None, v
    pairs = []
    for item in text.split(","):
        w, v = item.split(":")
        pairs.append((float(w), float(v)))
    return pairs, None


def check_spectrum(el, where):
    pairs, const = spectrum(el)
    name = el.get("name")
    if pairs is None:
        need(name in ("specular_reflectance", "reflectance"),
             "%s: %s is a constant (expected a spectrum on the grid)" % (where, name))
        need(0 <= const <= 1, "%s: %s = %g (expected 0..1)" % (where, name, const))
        return
    wl = [w for w, _ in pairs]
    vals = [v for _, v in pairs]
    need(all(b > a for a, b in zip(wl, wl[1:])),
         "%s: %s: wavelengths not strictly increasing" % (where, name))
    grid = LIGHT_GRID if name in ("irradiance", "radiance") else MATERIAL_GRID
    need(wl == grid, "%s: %s: %d wavelengths %g..%g (expected %d on %s)"
         % (where, name, len(wl), wl[0], wl[-1], len(grid), "400-700 nm" if grid is LIGHT_GRID
            else "360, 400-700 nm, 830"))
    inner = [v for w, v in pairs if 400 <= w <= 700]
    need(len(inner) == 61, "%s: %s: %d values on 400-700 nm (expected 61)" % (where, name,
                                                                              len(inner)))
    need(all(math.isfinite(v) and v >= 0 for v in vals), "%s: %s: a value < 0 or not finite"
         % (where, name))
    if name == "eta":
        need(all(v > 0 for v in vals), "%s: eta <= 0" % where)
    if name in ("diffuse_reflectance", "reflectance"):
        need(all(v <= 1 for v in vals), "%s: %s > 1" % (where, name))


def check_plugin(el, kind, ids, refs, files, base, path):
    typ = el.get("type")
    need(kind in ALLOWED, "%s: unknown plugin kind <%s>" % (path, kind))
    need(typ in ALLOWED[kind], "%s: <%s type=%r>: not a Mitsuba 3 %s plugin of the list"
         % (path, kind, typ, kind))
    params = ALLOWED[kind][typ]
    where = "%s/%s[%s]" % (path, kind, el.get("id") or typ)
    if el.get("id"):
        need(el.get("id") not in ids, "%s: id %r used twice" % (where, el.get("id")))
        ids[el.get("id")] = el
    nested = 0
    seen = set()
    for ch in el:
        if ch.tag in PROPERTY_TAGS:
            name = ch.get("name")
            need(name in params, "%s: parameter %r is not one of %s's (%s)"
                 % (where, name, typ, ", ".join(sorted(params)) or "none"))
            need(ch.tag in params[name], "%s: %s given as <%s> (expected %s)"
                 % (where, name, ch.tag, " or ".join(params[name])))
            need(name not in seen, "%s: %s given twice" % (where, name))
            seen.add(name)
            if (typ, name) in CHOICES:
                need(ch.get("value") in CHOICES[(typ, name)], "%s: %s = %r (expected %s)"
                     % (where, name, ch.get("value"), CHOICES[(typ, name)]))
            if ch.tag == "spectrum":
                check_spectrum(ch, where)
            if ch.tag == "float":
                v = float(ch.get("value"))
                need(math.isfinite(v), "%s: %s not finite" % (where, name))
                if name == "weight":
                    need(0 <= v <= 1, "%s: weight %g outside 0..1" % (where, v))
                if name in ("alpha", "fov", "near_clip", "far_clip", "int_ior", "ext_ior"):
                    need(v > 0, "%s: %s = %g (expected > 0)" % (where, name, v))
            if ch.tag == "integer":
                need(int(ch.get("value")) >= 0, "%s: %s < 0" % (where, name))
            if ch.tag == "boolean":
                need(ch.get("value") in ("true", "false"), "%s: %s" % (where, name))
            if ch.tag == "string" and name == "filename":
                f = os.path.join(base, ch.get("value"))
                need(os.path.isfile(f), "%s: file %s does not exist" % (where, f))
                files.append((f, el))
            if ch.tag == "transform":
                kids = list(ch)
                need(len(kids) == 1 and kids[0].tag == "lookat", "%s: to_world: expected one "
                     "<lookat>" % where)
                for a in ("origin", "target", "up"):
                    v = [float(x) for x in kids[0].get(a).split(",")]
                    need(len(v) == 3 and all(map(math.isfinite, v)), "%s: lookat %s" % (where, a))
            if ch.tag == "vector":
                v = [float(x) for x in ch.get("value").split(",")]
                need(len(v) == 3 and any(v), "%s: %s" % (where, name))
        elif ch.tag == "ref":
            refs.append((ch.get("id"), where))
        else:
            need(ch.tag in NESTED.get(kind, set()), "%s: <%s> cannot be nested in a %s"
                 % (where, ch.tag, kind))
            nested += 1
            check_plugin(ch, ch.tag, ids, refs, files, base, where)
    if typ == "blendbsdf":
        need(nested == 2, "%s: blendbsdf holds %d BSDFs (expected 2)" % (where, nested))
    if typ == "twosided":
        need(nested == 1, "%s: twosided holds %d BSDFs (expected 1)" % (where, nested))
    if typ in ("roughconductor", "conductor"):
        need("eta" in seen and "k" in seen and "material" not in seen,
             "%s: expected eta and k (spectra), no material preset" % where)
    if typ == "roughplastic":
        need("int_ior" in seen and "diffuse_reflectance" in seen, "%s: int_ior and "
             "diffuse_reflectance expected" % where)


def ply_header(path):
    with open(path, "rb") as f:
        head = b""
        while b"end_header\n" not in head:
            chunk = f.read(256)
            need(chunk, "%s: no end_header" % path)
            head += chunk
    lines = head.split(b"end_header\n")[0].decode("ascii").splitlines()
    need(lines[0] == "ply", "%s: not a PLY" % path)
    need("format binary_little_endian 1.0" in lines, "%s: not binary little-endian" % path)
    counts = {}
    for ln in lines:
        w = ln.split()
        if w and w[0] == "element":
            counts[w[1]] = int(w[2])
        if w[:2] == ["property", "list"]:
            need(w[-1] in ("vertex_indices", "vertex_index"), "%s: list %s" % (path, w[-1]))
    need(counts.get("vertex", 0) > 0 and counts.get("face", 0) > 0, "%s: empty mesh" % path)
    size = os.path.getsize(path)
    need(size >= len(head.split(b"end_header\n")[0]) + counts["face"] * 13,
         "%s: shorter than its faces" % path)
    return counts


def bsdf_by_id(ids, i):
    need(i in ids, "no plugin of id %r" % i)
    return ids[i]


def fresnel0(n, k):
    return ((n - 1) ** 2 + k ** 2) / ((n + 1) ** 2 + k ** 2)


def main(argv):
    xml = argv[1]
    scene_json = None
    models = {}
    i = 2
    while i < len(argv):
        if argv[i] == "--scene":
            scene_json = json.load(open(argv[i + 1]))
            i += 2
        elif argv[i] == "--model-csv":
            name, csv = argv[i + 1].split("=", 1)
            models[name] = csv
            i += 2
        else:
            raise SystemExit("usage: mitsuba_check.py SCENE.xml [--scene S.json] "
                             "[--model-csv NAME=CSV]")
    root = ET.parse(xml).getroot()
    need(root.tag == "scene" and root.get("version") == "3.0.0",
         "root: expected <scene version=\"3.0.0\">")
    ids, refs, files = {}, [], []
    base = os.path.dirname(os.path.abspath(xml))
    kinds = {}
    for el in root:
        need(el.tag in ALLOWED, "scene: unexpected <%s>" % el.tag)
        kinds[el.tag] = kinds.get(el.tag, 0) + 1
        check_plugin(el, el.tag, ids, refs, files, base, "scene")
    for r, where in refs:
        need(r in ids, "%s: <ref id=%r> names no plugin" % (where, r))
        need(ids[r].tag == "bsdf", "%s: <ref id=%r> is no BSDF" % (where, r))
    need(kinds.get("sensor") == 1 and kinds.get("integrator") == 1,
         "expected one sensor and one integrator")
    need(kinds.get("emitter", 0) >= 1 and kinds.get("shape", 0) >= 1,
         "expected an emitter and a shape")
    faces = 0
    for f, el in files:
        counts = ply_header(f)
        faces += counts["face"]
        shape_refs = [c.get("id") for c in el if c.tag == "ref"]
        need(len(shape_refs) == 1, "%s: one <ref> to its BSDF expected" % f)
    if scene_json:
        cam = scene_json["camera"]
        sensor = root.find("sensor")
        look = sensor.find("transform/lookat")
        for a, key in (("origin", "position"), ("target", "look_at")):
            v = [float(x) for x in look.get(a).split(",")]
            need(all(abs(x - y) < 1e-6 for x, y in zip(v, cam[key])),
                 "sensor %s %s != the scene's camera %s %s" % (a, v, key, cam[key]))
        fov = float(sensor.find("float[@name='fov']").get("value"))
        need(abs(fov - cam["fov_deg"]) < 1e-6 * max(1.0, abs(fov)) and
             sensor.find("string[@name='fov_axis']").get("value") == "y",
             "sensor fov %g (axis y) != the scene's vertical %g" % (fov, cam["fov_deg"]))
        film = sensor.find("film")
        for k in ("width", "height"):
            if k in cam:
                need(int(film.find("integer[@name='%s']" % k).get("value")) == cam[k],
                     "film %s != the scene's" % k)
        if "light" in scene_json:
            d = scene_json["light"]["direction"]
            n = math.sqrt(sum(x * x for x in d))
            em = [e for e in root.findall("emitter") if e.get("type") == "directional"]
            need(len(em) == 1, "one directional emitter expected (the scene has a light)")
            v = [float(x) for x in em[0].find("vector[@name='direction']").get("value").split(",")]
            need(all(abs(a + b / n) < 1e-6 for a, b in zip(v, d)),
                 "directional direction %s is not minus the scene's light direction %s" % (v, d))
    for name, csv in models.items():
        el = bsdf_by_id(ids, name)
        conds = [c for c in el.iter("bsdf") if c.get("type") in ("roughconductor", "conductor")]
        need(conds, "%s: no conductor inside" % name)
        rows = [ln.split(",") for ln in open(csv).read().splitlines()[1:] if ln.strip()]
        r0 = [float(r[1]) for r in rows]
        # the first conductor of the material is its (first) metal; a metal's lobes share n, k
        sp = {c.get("name"): spectrum(c)[0] for c in conds[0] if c.tag == "spectrum"}
        eta = [v for w, v in sp["eta"] if 400 <= w <= 700]
        k = [v for w, v in sp["k"] if 400 <= w <= 700]
        worst = max(abs(fresnel0(a, b) - r) for a, b, r in zip(eta, k, r0))
        need(worst < 1e-4, "%s: normal-incidence reflectance from the XML's eta, k differs "
             "from kogei model's by %.2g" % (name, worst))
        print("mitsuba_check: %s: R(0) from eta, k within %.1e of kogei model" % (name, worst))
    print("mitsuba_check: %s: %d plugins with ids, %d shapes (%d triangles), %s: ok"
          % (xml, len(ids), len(files), faces, ", ".join("%d %s" % (v, k)
                                                       for k, v in sorted(kinds.items()))))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv))
    except Fail as e:
        print("FAIL: mitsuba_check: %s" % e)
        sys.exit(1)
