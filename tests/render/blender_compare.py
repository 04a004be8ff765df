#!/usr/bin/env python3
"""Per material region, the mean colour of Blender's render against kogei's: CIEDE2000.

usage: blender_compare.py KOGEI_XYZ.tif KOGEI_LABELS.hdr BLENDER.f32 [--max-de 5]
                          [--table OUT.md]

KOGEI_XYZ.tif: `kogei render --linear` (CIE 1931 XYZ, float32, Y = 1 for a white
diffuser lit by a light of intensity 1). KOGEI_LABELS.hdr: `--truth-labels` of the same
render (which library material each pixel shows; class 0 background). BLENDER.f32:
tests/render/blender_render.py's raw output (linear Rec. 709 RGB + alpha, the same view).

Both images stay on their absolute scale: nothing is normalised per image. The lights
were set in the same units (blender_render.py), so a white diffuser lit at intensity 1
is Y = 1 in both. Blender's linear Rec. 709 (D65 white) goes to XYZ by the sRGB matrix
(IEC 61966-2-1); both means are taken in XYZ over the same pixels: those of the class
whose four neighbours are of the same class (region edges, where the two renderers'
sub-pixel coverage differs, are left out) and which Blender covers (alpha > 0.99).
CIELAB with the reference white D65 at Y = 1 (the image scale's white), then CIEDE2000
(G. Sharma, W. Wu, E. N. Dalal, Color Res. Appl. 30(1), 21-30, 2005).
The view is checked first: where kogei sees the object (class > 0) and where Blender's
alpha says it does must agree on at least 99 % of the pixels.
Exit 1 when a region's dE00 exceeds --max-de (default 5) or the views disagree."""
import math
import struct
import sys

RGB2XYZ = ((0.4124, 0.3576, 0.1805), (0.2126, 0.7152, 0.0722), (0.0193, 0.1192, 0.9505))
WHITE = (0.95047, 1.0, 1.08883)


def read_tiff_float3(path):
    data = open(path, "rb").read()
    bo = "<" if data[:2] == b"II" else ">"
    (ifd,) = struct.unpack(bo + "I", data[4:8])
    (n,) = struct.unpack(bo + "H", data[ifd:ifd + 2])
    tags = {}
    for i in range(n):
        e = data[ifd + 2 + 12 * i: ifd + 14 + 12 * i]
        tag, typ, count = struct.unpack(bo + "HHI", e[:8])
        size = {3: 2, 4: 4}.get(typ, 1) * count
        fmt = {3: "H", 4: "I"}.get(typ)
        raw = e[8:12] if size <= 4 else data[struct.unpack(bo + "I", e[8:12])[0]:][:size]
        if fmt:
            tags[tag] = struct.unpack(bo + fmt * count, raw[:size])
    w, h = tags[256][0], tags[257][0]
    if tags.get(259, (1,))[0] != 1 or tags.get(258, (0,))[0] != 32 or tags.get(277, (1,))[0] != 3 \
            or tags.get(339, (1,))[0] != 3 or tags.get(284, (1,))[0] != 1:
        raise SystemExit("%s: expected an uncompressed chunky float32 RGB TIFF" % path)
    buf = b"".join(data[o:o + c] for o, c in zip(tags[273], tags[279]))
    vals = struct.unpack(bo + "%df" % (3 * w * h), buf[:12 * w * h])
    return w, h, vals


def read_envi_labels(hdr):
    text = open(hdr).read()
    fields = {}
    for key in ("samples", "lines"):
        for ln in text.splitlines():
            if ln.split("=")[0].strip() == key:
                fields[key] = int(ln.split("=")[1])
    names = text.split("class names")[1].split("{")[1].split("}")[0]
    names = [s.strip() for s in names.split(",")]
    img = hdr[:-4] + ".img"
    lab = open(img, "rb").read()
    return fields["samples"], fields["lines"], names, lab


def read_blender(path):
    data = open(path, "rb").read()
    head, rest = data.split(b"\n", 1)
    magic, ver, w, h, c = head.split()
    if magic != b"KOGEI-BLENDER-RAW" or c != b"4":
        raise SystemExit("%s: not a blender_render.py raw file" % path)
    w, h = int(w), int(h)
    return w, h, struct.unpack("<%df" % (4 * w * h), rest[:16 * w * h])


def lab(xyz):
    def f(t):
        return t ** (1 / 3) if t > (6 / 29) ** 3 else t / (3 * (6 / 29) ** 2) + 4 / 29
    fx, fy, fz = (f(max(v, 0.0) / wv) for v, wv in zip(xyz, WHITE))
    return 116 * fy - 16, 500 * (fx - fy), 200 * (fy - fz)


def de2000(l1, l2):
    L1, a1, b1 = l1
    L2, a2, b2 = l2
    c1, c2 = math.hypot(a1, b1), math.hypot(a2, b2)
    cm = (c1 + c2) / 2
    g = 0.5 * (1 - math.sqrt(cm ** 7 / (cm ** 7 + 25 ** 7)))
    a1p, a2p = (1 + g) * a1, (1 + g) * a2
    c1p, c2p = math.hypot(a1p, b1), math.hypot(a2p, b2)
    h1p = math.degrees(math.atan2(b1, a1p)) % 360 if c1p else 0.0
    h2p = math.degrees(math.atan2(b2, a2p)) % 360 if c2p else 0.0
    dl, dc = L2 - L1, c2p - c1p
    if c1p * c2p == 0:
        dh = 0.0
    elif abs(h2p - h1p) <= 180:
        dh = h2p - h1p
    elif h2p - h1p > 180:
        dh = h2p - h1p - 360
    else:
        dh = h2p - h1p + 360
    dH = 2 * math.sqrt(c1p * c2p) * math.sin(math.radians(dh / 2))
    lm, cmp_ = (L1 + L2) / 2, (c1p + c2p) / 2
    if c1p * c2p == 0:
        hm = h1p + h2p
    elif abs(h1p - h2p) <= 180:
        hm = (h1p + h2p) / 2
    elif h1p + h2p < 360:
        hm = (h1p + h2p + 360) / 2
    else:
        hm = (h1p + h2p - 360) / 2
    t = (1 - 0.17 * math.cos(math.radians(hm - 30)) + 0.24 * math.cos(math.radians(2 * hm))
         + 0.32 * math.cos(math.radians(3 * hm + 6)) - 0.20 * math.cos(math.radians(4 * hm - 63)))
    dtheta = 30 * math.exp(-((hm - 275) / 25) ** 2)
    rc = 2 * math.sqrt(cmp_ ** 7 / (cmp_ ** 7 + 25 ** 7))
    sl = 1 + 0.015 * (lm - 50) ** 2 / math.sqrt(20 + (lm - 50) ** 2)
    sc = 1 + 0.045 * cmp_
    sh = 1 + 0.015 * cmp_ * t
    rt = -math.sin(math.radians(2 * dtheta)) * rc
    return math.sqrt((dl / sl) ** 2 + (dc / sc) ** 2 + (dH / sh) ** 2 + rt * (dc / sc) * (dH / sh))


def self_test():
    # Sharma et al. (2005), Table 1, pairs 1, 7 and 17
    pairs = [((50, 2.6772, -79.7751), (50, 0, -82.7485), 2.0425),
             ((50, 0, 0), (50, -1, 2), 2.3669),
             ((50, 2.5, 0), (73, 25, -18), 27.1492)]
    for a, b, want in pairs:
        got = de2000(a, b)
        if abs(got - want) > 1e-4:
            raise SystemExit("blender_compare.py: dE2000 self-test: %.4f, expected %.4f"
                             % (got, want))


def main(argv):
    self_test()
    if len(argv) < 4:
        raise SystemExit(__doc__)
    max_de, table = 5.0, None
    i = 4
    while i < len(argv):
        if argv[i] == "--max-de":
            max_de = float(argv[i + 1])
        elif argv[i] == "--table":
            table = argv[i + 1]
        else:
            raise SystemExit("blender_compare.py: bad argument %r" % argv[i])
        i += 2
    kw, kh, kxyz = read_tiff_float3(argv[1])
    lw, lh, names, labels = read_envi_labels(argv[2])
    bw, bh, brgba = read_blender(argv[3])
    if not (kw == lw == bw and kh == lh == bh):
        raise SystemExit("sizes differ: kogei %dx%d, labels %dx%d, Blender %dx%d"
                         % (kw, kh, lw, lh, bw, bh))
    w, h = kw, kh
    agree = 0
    sums = {}
    for y in range(h):
        for x in range(w):
            p = y * w + x
            c = labels[p]
            a = brgba[4 * p + 3]
            agree += (c > 0) == (a > 0.5)
            if c == 0 or a < 0.99:
                continue
            if x == 0 or y == 0 or x == w - 1 or y == h - 1 or labels[p - 1] != c or \
                    labels[p + 1] != c or labels[p - w] != c or labels[p + w] != c:
                continue
            r, g, b = brgba[4 * p:4 * p + 3]
            bx = [m[0] * r + m[1] * g + m[2] * b for m in RGB2XYZ]
            s = sums.setdefault(c, [0, [0.0] * 3, [0.0] * 3])
            s[0] += 1
            for k in range(3):
                s[1][k] += kxyz[3 * p + k]
                s[2][k] += bx[k]
    frac = agree / (w * h)
    rows = []
    worst = 0.0
    for c in sorted(sums):
        n, ks, bs = sums[c]
        if n < 20:
            continue
        kx = [v / n for v in ks]
        bx = [v / n for v in bs]
        kl, bl = lab(kx), lab(bx)
        de = de2000(kl, bl)
        worst = max(worst, de)
        rows.append((names[c], n, kl, bl, kx[1], bx[1], de))
    out = ["| material | pixels | kogei L\\* a\\* b\\* | Blender L\\* a\\* b\\* | Y Blender / kogei "
           "| ΔE00 |", "|---|---:|---|---|---:|---:|"]
    for name, n, kl, bl, ky, by, de in rows:
        out.append("| %s | %d | %.1f %.1f %.1f | %.1f %.1f %.1f | %.3f | %.2f |"
                   % (name, n, kl[0], kl[1], kl[2], bl[0], bl[1], bl[2], by / ky, de))
    print("\n".join(out))
    print("view: kogei's object pixels and Blender's alpha agree on %.2f %% of the image"
          % (100 * frac))
    if table:
        open(table, "w").write("\n".join(out) + "\n")
    ok = True
    if frac < 0.99:
        print("FAIL: the views differ (%.2f %% agreement, expected >= 99 %%)" % (100 * frac))
        ok = False
    if len(rows) < 2:
        print("FAIL: fewer than two material regions to compare")
        ok = False
    for name, n, kl, bl, ky, by, de in rows:
        if de > max_de:
            print("FAIL: %s: dE00 %.2f > %g" % (name, de, max_de))
            ok = False
    print("worst dE00 %.2f over %d regions (limit %g)" % (worst, len(rows), max_de))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
