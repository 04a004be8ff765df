#!/usr/bin/env python3
"""An object's access copy and manifest, and the image server serving them (called by
test_iiif.sh, which processes the session and starts the servers).

usage: iiif_check.py OUTDIR OBJECT PORT TMP
TMP holds master_srgb.tif and master_srgb.raw: the master through its own profile to
sRGB by LittleCMS (tificc), as 16-bit samples.
"""
import json
import struct
import subprocess
import sys
import urllib.request

import numpy as np

failures = []


def fail(msg):
    failures.append(msg)
    print("FAIL: " + msg)


def tiff_ifds(path):
    """Every IFD of a little-endian classic TIFF as {tag: value or [values]}."""
    d = open(path, "rb").read()
    if d[:4] != b"II*\0":
        raise ValueError("%s: not a little-endian TIFF" % path)
    sizes = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 7: 1, 16: 8}
    fmt = {1: "B", 2: "s", 3: "H", 4: "I", 7: "B", 16: "Q"}
    ifds = []
    (off,) = struct.unpack_from("<I", d, 4)
    while off:
        (n,) = struct.unpack_from("<H", d, off)
        tags = {}
        for i in range(n):
            tag, typ, cnt = struct.unpack_from("<HHI", d, off + 2 + 12 * i)
            size = sizes.get(typ, 1) * cnt
            at = off + 2 + 12 * i + 8
            if size > 4:
                (at,) = struct.unpack_from("<I", d, at)
            if typ in (2, 7) or (typ == 1 and cnt > 4):
                tags[tag] = d[at:at + cnt]
            elif typ in fmt:
                v = struct.unpack_from("<%d%s" % (cnt, fmt[typ]), d, at)
                tags[tag] = v[0] if cnt == 1 else list(v)
        ifds.append(tags)
        (off,) = struct.unpack_from("<I", d, off + 2 + 12 * n)
    return ifds


def srgb_to_lab(rgb):
    """sRGB (0..1, encoded) to CIELAB under D65 (IEC 61966-2-1)."""
    c = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    m = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722],
                  [0.0193, 0.1192, 0.9505]])
    xyz = c @ m.T / np.array([0.95047, 1.0, 1.08883])
    f = np.where(xyz > (6 / 29) ** 3, np.cbrt(xyz), xyz / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.stack([116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]),
                     200 * (f[..., 1] - f[..., 2])], -1)


def de2000(lab1, lab2):
    """CIEDE2000 (Sharma, Wu and Dalal 2005), kL = kC = kH = 1."""
    L1, a1, b1 = np.moveaxis(lab1, -1, 0)
    L2, a2, b2 = np.moveaxis(lab2, -1, 0)
    C1, C2 = np.hypot(a1, b1), np.hypot(a2, b2)
    Cm = (C1 + C2) / 2
    G = 0.5 * (1 - np.sqrt(Cm ** 7 / (Cm ** 7 + 25.0 ** 7)))
    a1p, a2p = (1 + G) * a1, (1 + G) * a2
    C1p, C2p = np.hypot(a1p, b1), np.hypot(a2p, b2)
    h1p = np.degrees(np.arctan2(b1, a1p)) % 360
    h2p = np.degrees(np.arctan2(b2, a2p)) % 360
    dLp, dCp = L2 - L1, C2p - C1p
    dh = h2p - h1p
    dh = np.where(dh > 180, dh - 360, np.where(dh < -180, dh + 360, dh))
    dh = np.where(C1p * C2p == 0, 0, dh)
    dHp = 2 * np.sqrt(C1p * C2p) * np.sin(np.radians(dh / 2))
    Lpm, Cpm = (L1 + L2) / 2, (C1p + C2p) / 2
    hs = h1p + h2p
    hpm = np.where(np.abs(h1p - h2p) > 180, np.where(hs < 360, hs + 360, hs - 360), hs) / 2
    hpm = np.where(C1p * C2p == 0, hs, hpm)
    T = (1 - 0.17 * np.cos(np.radians(hpm - 30)) + 0.24 * np.cos(np.radians(2 * hpm))
         + 0.32 * np.cos(np.radians(3 * hpm + 6)) - 0.20 * np.cos(np.radians(4 * hpm - 63)))
    dtheta = 30 * np.exp(-(((hpm - 275) / 25) ** 2))
    Rc = 2 * np.sqrt(Cpm ** 7 / (Cpm ** 7 + 25.0 ** 7))
    Sl = 1 + 0.015 * (Lpm - 50) ** 2 / np.sqrt(20 + (Lpm - 50) ** 2)
    Sc, Sh = 1 + 0.045 * Cpm, 1 + 0.015 * Cpm * T
    Rt = -np.sin(np.radians(2 * dtheta)) * Rc
    return np.sqrt((dLp / Sl) ** 2 + (dCp / Sc) ** 2 + (dHp / Sh) ** 2
                   + Rt * (dCp / Sc) * (dHp / Sh))


def get(url):
    with urllib.request.urlopen(url, timeout=30) as r:
        return r.status, r.headers.get("Content-Type", ""), r.read()


def main():
    out, obj, port, tmp = sys.argv[1:5]
    pj = json.load(open(out + "/process.json"))
    o = [x for x in pj["objects"] if x["capture"] == obj][0]
    master = tiff_ifds("%s/%s/master.tif" % (out, obj))[0]
    W, H = master[256], master[257]
    print("master.tif: %dx%d" % (W, H))

    # the access copy, level by level
    ifds = tiff_ifds("%s/%s/access.tif" % (out, obj))
    # the levels the pyramid must have: halved until one fits a 256 x 256 tile
    want = [(W, H)]
    while want[-1][0] > 256 or want[-1][1] > 256:
        want.append(((want[-1][0] + 1) // 2, (want[-1][1] + 1) // 2))
    got = [(t[256], t[257]) for t in ifds]
    print("access.tif levels: %s" % got)
    if len(got) != len(want) or any(abs(g[0] - w[0]) > 1 or abs(g[1] - w[1]) > 1
                                     for g, w in zip(got, want)):
        fail("levels %s, expected %s (each half the one before, down to one tile)"
             % (got, want))
    for i, t in enumerate(ifds):
        bits = t.get(258)
        if t.get(322) != 256 or t.get(323) != 256:
            fail("level %d: tiles %sx%s, expected 256x256" % (i, t.get(322), t.get(323)))
        if t.get(259) != 7:
            fail("level %d: compression %s, expected 7 (JPEG)" % (i, t.get(259)))
        if t.get(277) != 3 or bits not in (8, [8, 8, 8]):
            fail("level %d: %s samples of %s bits, expected 3 of 8" % (i, t.get(277), bits))
    xmp = ifds[0].get(700, b"").decode("utf-8", "replace")
    if "<dc:identifier>TNM-E-20417</dc:identifier>" not in xmp:
        fail("access.tif's XMP has no dc:identifier TNM-E-20417")
    if "Tsuba with waves" not in xmp or "kogei:HeldOutDE00Mean" not in xmp:
        fail("access.tif's XMP lacks the title or the held-out colour error")
    acc = o["access"]
    if (acc["width"], acc["height"], acc["levels"], acc["tile"], acc["quality"]) != \
            (W, H, len(want), 256, 90):
        fail("process.json access %r" % acc)

    # the manifest
    base = "http://127.0.0.1:%s" % port
    m = json.load(open("%s/%s/manifest.json" % (out, obj)))
    if m.get("@context") != "http://iiif.io/api/presentation/3/context.json":
        fail("@context %r" % m.get("@context"))
    if m.get("type") != "Manifest" or m.get("id") != base + "/files/obj/manifest.json":
        fail("type %r, id %r" % (m.get("type"), m.get("id")))
    if m["label"] != {"none": ["Tsuba with waves"]}:
        fail("label %r" % m["label"])
    md = {e["label"]["en"][0]: list(e["value"].values())[0] for e in m["metadata"]}
    if md.get("Accession") != ["TNM-E-20417"] or md.get("Operator") != ["Sato"] or \
            md.get("Date") != ["2026-12-01"]:
        fail("metadata %r" % md)
    shares = md.get("Materials found (share of the image)", [])
    for c in o["classes"]:
        if c["name"] in ("background", "unknown"):
            continue
        if "%s: %.1f %%" % (c["name"], 100 * c["fraction"]) not in shares:
            fail("material %s (%.4f) not among %r" % (c["name"], c["fraction"], shares))
    if not shares:
        fail("no materials in the metadata")
    de = o["identity"]["colour_accuracy"]["de00_mean"]
    held = md.get("Held-out colour error (CIEDE2000)", [""])[0]
    if not held.startswith("mean %.2f," % de):
        fail("held-out dE00 %r, process.json says %.4f" % (held, de))
    legend = md.get("Label map legend (class: colour, share)", [])
    for c in o["classes"]:
        col = "#%02x%02x%02x" % tuple(c["colour"])
        if not any(x.startswith("%s: %s" % (c["name"], col)) for x in legend):
            fail("legend lacks %s %s: %r" % (c["name"], col, legend))
    canvases = m["items"]
    if len(canvases) != 1 or canvases[0]["type"] != "Canvas" or \
            (canvases[0]["width"], canvases[0]["height"]) != (W, H):
        fail("canvases %r" % [(c["type"], c.get("width"), c.get("height")) for c in canvases])
    annos = canvases[0]["items"][0]["items"]
    if [a["motivation"] for a in annos] != ["painting", "painting"]:
        fail("annotations %r" % [a["motivation"] for a in annos])
    body = annos[0]["body"]
    svc = body["service"][0]
    service = base + "/iiif/obj/access.tif"
    if svc.get("@id") != service or svc.get("@type") != "ImageService2":
        fail("service %r, expected %s (ImageService2)" % (svc, service))
    if (body["width"], body["height"]) != (W, H) or annos[0]["target"] != canvases[0]["id"]:
        fail("image body %r" % body)
    lab = annos[1]["body"]
    if lab["id"] != base + "/files/obj/labels_layer.png" or lab["format"] != "image/png":
        fail("label layer %r" % lab)

    # the server: info.json
    st, ctype, data = get(service + "/info.json")
    info = json.loads(data)
    print("info.json: %dx%d, tiles %r, context %s" % (info["width"], info["height"],
                                                      info["tiles"], info["@context"]))
    if (info["width"], info["height"]) != (W, H):
        fail("info.json %dx%d, the master %dx%d" % (info["width"], info["height"], W, H))
    if info["@context"] != "http://iiif.io/api/image/2/context.json":
        fail("info.json speaks %s: the manifest says ImageService2" % info["@context"])
    if info["@id"] != service:
        fail("info.json @id %s, the manifest's service %s" % (info["@id"], service))
    tiles = info["tiles"][0]
    if tiles["width"] != 256 or tiles.get("height", 256) != 256 or \
            tiles["scaleFactors"] != [2 ** i for i in range(len(ifds))]:
        fail("tiles %r, expected 256 with scale factors of %d levels" % (tiles, len(ifds)))

    # a region at half size against the master's sRGB rendering, averaged 2 x 2
    x, y, w, h = W // 8 * 2, H // 8 * 2, W // 4 * 2, H // 4 * 2
    st, ctype, data = get("%s/%d,%d,%d,%d/%d,/0/default.jpg" % (service, x, y, w, h, w // 2))
    if ctype != "image/jpeg":
        fail("region: %s, expected image/jpeg" % ctype)
    open(tmp + "/region.jpg", "wb").write(data)
    subprocess.run(["vips", "rawsave", tmp + "/region.jpg", tmp + "/region.raw"], check=True)
    hdr = subprocess.run(["vipsheader", "-f", "width", tmp + "/region.jpg"], check=True,
                         capture_output=True, text=True).stdout.strip()
    rw = int(hdr)
    reg = np.fromfile(tmp + "/region.raw", np.uint8)
    rh = reg.size // (3 * rw)
    if (rw, rh) != (w // 2, h // 2):
        fail("region %dx%d, expected %dx%d" % (rw, rh, w // 2, h // 2))
        return
    reg = reg.reshape(rh, rw, 3) / 255.0
    ref = np.fromfile(tmp + "/master_srgb.raw", np.uint16).reshape(H, W, 3) / 65535.0
    ref = ref[y:y + h, x:x + w]
    ref2 = ref.reshape(rh, 2, rw, 2, 3).mean(axis=(1, 3))
    d = de2000(srgb_to_lab(ref2), srgb_to_lab(reg))
    print("region %d,%d,%d,%d at %dx%d, pixel by pixel against the master's sRGB averaged "
          "2 x 2: dE00 mean %.3f, median %.3f, p95 %.3f (JPEG's loss of the master's pixel "
          "noise and of colour at edges: not judged)"
          % (x, y, w, h, rw, rh, d.mean(), np.median(d), np.percentile(d, 95)))
    # the colours of the surfaces: blocks of B x B served pixels (2B x 2B of the master)
    # that lie, with a margin of 2 master pixels, inside one class of the object's label
    # map (labels.img, one byte a pixel), averaged in linear light
    B = 4
    labels = np.fromfile("%s/%s/labels.img" % (out, obj), np.uint8).reshape(H, W)
    lab = labels[y - 2:y + h + 2, x - 2:x + w + 2]
    nby, nbx = rh // B, rw // B
    lin = lambda c: np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    enc = lambda c: np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    a, b = [], []
    for by in range(nby):
        for bx in range(nbx):
            win = lab[by * 2 * B:(by + 1) * 2 * B + 4, bx * 2 * B:(bx + 1) * 2 * B + 4]
            if win.min() != win.max():
                continue
            a.append(lin(ref[by * 2 * B:(by + 1) * 2 * B, bx * 2 * B:(bx + 1) * 2 * B])
                     .reshape(-1, 3).mean(0))
            b.append(lin(reg[by * B:(by + 1) * B, bx * B:(bx + 1) * B]).reshape(-1, 3).mean(0))
    if len(a) < nby * nbx // 4:
        fail("only %d of %d blocks inside one class: the test image has too few surfaces"
             % (len(a), nby * nbx))
        return
    db = de2000(srgb_to_lab(enc(np.array(a))), srgb_to_lab(enc(np.array(b))))
    print("the colours of %d surface blocks of %dx%d served pixels (of %d): dE00 mean %.3f, "
          "p95 %.3f, max %.3f" % (len(a), B, B, nby * nbx, db.mean(), np.percentile(db, 95),
                                  db.max()))
    if not db.mean() <= 1.0:
        fail("mean dE00 of the surfaces' colours %.3f > 1" % db.mean())
    # the same region from the top of the pyramid (a quarter or less) is served too
    st, ctype, data = get("%s/full/%d,/0/default.jpg" % (service, (W + 3) // 4))
    if st != 200 or data[:2] != b"\xff\xd8":
        fail("full image at a quarter: %d %s" % (st, ctype))


if __name__ == "__main__":
    main()
    sys.exit(1 if failures else 0)
