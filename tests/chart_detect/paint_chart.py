#!/usr/bin/env python3
"""Change a chart photograph written by `kogei sim chart` where the chart is: cover
patches with a card, paint a patch another patch's colour, put part of the chart in
shadow. Places are in the layout's millimetres, mapped to pixels through the truth
file's HOMOGRAPHY (card mm -> pixel); every pixel whose centre maps inside is changed.

usage: paint_chart.py IN.tif TRUTH.cgats LAYOUT.json OUT.tif OP...
  cover:ID[+ID...]:V        a card of camera value V (0..1, all channels) over the
                            patches' bounding box (their full size, 2 mm beyond)
  paint:ID:SRC              patch ID (its full size) painted SRC's truth colour
  light:X0:Y0:X1:Y1:F       the light on the chart's rectangle (mm) times F
  ramp:F0:F1                the light times F0 at the chart area's left edge, F1 at
                            its right edge, linear between (a lamp's falloff)

The TIFF is the simulator's: uncompressed, little-endian, 8 or 16 bits, 1 or 3
samples per pixel, strips in order. Other TIFFs are refused."""
import json
import struct
import sys


def fail(msg):
    sys.stderr.write("paint_chart.py: %s\n" % msg)
    sys.exit(1)


def read_tiff(path):
    b = bytearray(open(path, "rb").read())
    if b[:4] != b"II*\x00":
        fail("%s: not a little-endian TIFF" % path)
    off = struct.unpack_from("<I", b, 4)[0]
    tags = {}
    for k in range(struct.unpack_from("<H", b, off)[0]):
        tag, typ, cnt, val = struct.unpack_from("<HHII", b, off + 2 + 12 * k)
        size = {3: 2, 4: 4}.get(typ)
        if size is None:
            continue
        fmt = "<" + ("H" if typ == 3 else "I") * cnt
        if size * cnt <= 4:
            tags[tag] = struct.unpack_from(fmt, b, off + 2 + 12 * k + 8)
        else:
            tags[tag] = struct.unpack_from(fmt, b, val)
    if tags.get(259, (1,))[0] != 1:
        fail("%s: compressed TIFF" % path)
    w, h = tags[256][0], tags[257][0]
    spp = tags.get(277, (1,))[0]
    bits = tags[258][0]
    if bits not in (8, 16):
        fail("%s: %d bits per sample" % (path, bits))
    return b, w, h, spp, bits, list(tags[273]), list(tags[279])


def homography(truth):
    for line in open(truth):
        if line.startswith("HOMOGRAPHY "):
            return [float(x) for x in line.split('"')[1].split()]
    fail("%s: no HOMOGRAPHY" % truth)


def truth_rgb(truth, pid):
    lines = open(truth).read().split("\n")
    fields = [l for l in lines if l.startswith("SAMPLE_ID")][0].split("\t")
    for l in lines[lines.index("BEGIN_DATA") + 1:lines.index("END_DATA")]:
        v = l.split("\t")
        if v[0] == pid:
            return [float(v[fields.index(c)]) for c in ("FLAT_R", "FLAT_G", "FLAT_B")]
    fail("%s: no patch %s" % (truth, pid))


def inverse(H):
    a, b, c, d, e, f, g, h, i = H
    m = [e * i - f * h, c * h - b * i, b * f - c * e, f * g - d * i, a * i - c * g,
         c * d - a * f, d * h - e * g, b * g - a * h, a * e - b * d]
    det = a * m[0] + b * m[3] + c * m[6]
    return [x / det for x in m]


class Image:
    def __init__(self, path, truth):
        self.b, self.w, self.h, self.spp, self.bits, offs, counts = read_tiff(path)
        self.full = 255 if self.bits == 8 else 65535
        self.H = homography(truth)
        self.G = inverse(self.H)
        # every row's byte offset (the strips hold whole rows, in order)
        row = self.w * self.spp * self.bits // 8
        self.rows = []
        for o, n in zip(offs, counts):
            self.rows += [o + k * row for k in range(n // row)]

    def region(self, x0, y0, x1, y1):
        """Pixels (x, y, chart x mm) whose centres map inside the rectangle."""
        pts = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        px = []
        for X, Y in pts:
            H = self.H
            w = H[6] * X + H[7] * Y + H[8]
            px.append(((H[0] * X + H[1] * Y + H[2]) / w, (H[3] * X + H[4] * Y + H[5]) / w))
        lo_x = max(0, int(min(p[0] for p in px)) - 1)
        hi_x = min(self.w, int(max(p[0] for p in px)) + 2)
        lo_y = max(0, int(min(p[1] for p in px)) - 1)
        hi_y = min(self.h, int(max(p[1] for p in px)) + 2)
        G = self.G
        for y in range(lo_y, hi_y):
            for x in range(lo_x, hi_x):
                u, v = x + 0.5, y + 0.5
                w = G[6] * u + G[7] * v + G[8]
                X, Y = (G[0] * u + G[1] * v + G[2]) / w, (G[3] * u + G[4] * v + G[5]) / w
                if x0 <= X <= x1 and y0 <= Y <= y1:
                    yield x, y, X

    def put(self, x, y, fn):
        size = self.bits // 8
        at = self.rows[y] + x * self.spp * size
        fmt = "<B" if size == 1 else "<H"
        for c in range(self.spp):
            v = struct.unpack_from(fmt, self.b, at + c * size)[0] / self.full
            v = fn(c, v)
            struct.pack_into(fmt, self.b, at + c * size,
                             max(0, min(self.full, int(round(v * self.full)))))


def patch_rect(layout, pid, margin=0.0):
    for p in layout["patches"]:
        if p["id"] == pid:
            (cx, cy), (sw, sh) = p["center_mm"], p["size_mm"]
            return [cx - sw / 2 - margin, cy - sh / 2 - margin, cx + sw / 2 + margin,
                    cy + sh / 2 + margin]
    fail("layout %s: no patch %s" % (layout["name"], pid))


def main(argv):
    if len(argv) < 6:
        fail(__doc__)
    src, truth, layout_path, dst = argv[1:5]
    layout = json.load(open(layout_path))
    img = Image(src, truth)
    for op in argv[5:]:
        f = op.split(":")
        if f[0] == "cover" and len(f) == 3:
            rs = [patch_rect(layout, p, 2.0) for p in f[1].split("+")]
            r = [min(x[0] for x in rs), min(x[1] for x in rs), max(x[2] for x in rs),
                 max(x[3] for x in rs)]
            val = float(f[2])
            for x, y, _ in list(img.region(*r)):
                img.put(x, y, lambda c, v: val)
        elif f[0] == "paint" and len(f) == 3:
            rgb = truth_rgb(truth, f[2])
            for x, y, _ in list(img.region(*patch_rect(layout, f[1]))):
                img.put(x, y, lambda c, v: rgb[c] if img.spp == 3 else sum(rgb) / 3)
        elif f[0] == "light" and len(f) == 6:
            k = float(f[5])
            for x, y, _ in list(img.region(*[float(v) for v in f[1:5]])):
                img.put(x, y, lambda c, v: v * k)
        elif f[0] == "ramp" and len(f) == 3:
            a = layout["chart_area_mm"]
            f0, f1 = float(f[1]), float(f[2])
            for x, y, X in list(img.region(a[0], a[1], a[0] + a[2], a[1] + a[3])):
                k = f0 + (f1 - f0) * (X - a[0]) / a[2]
                img.put(x, y, lambda c, v: v * k)
        else:
            fail("unknown operation '%s'" % op)
    open(dst, "wb").write(img.b)


if __name__ == "__main__":
    main(sys.argv)
