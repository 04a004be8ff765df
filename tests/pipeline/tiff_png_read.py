"""A TIFF and PNG reader of the tests' own (no imaging library): enough to read back
what kogei writes. TIFF: baseline strips, uncompressed or LZW (TIFF 6.0 section 13),
the horizontal predictor (2) for integers and the floating-point predictor (3, TIFF
Technical Note 3); PNG: 8-bit RGB or RGBA, non-interlaced, the five filters."""
import struct
import zlib

import numpy as np

TYPES = {1: "B", 2: "s", 3: "H", 4: "I", 5: "II", 6: "b", 7: "B", 8: "h", 9: "i",
         10: "ii", 11: "f", 12: "d", 16: "Q"}


def tiff_tags(data):
    e = "<" if data[:2] == b"II" else ">"
    off = struct.unpack(e + "I", data[4:8])[0]
    n = struct.unpack(e + "H", data[off:off + 2])[0]
    tags = {}
    for i in range(n):
        tag, typ, cnt, val = struct.unpack(e + "HHI4s", data[off + 2 + 12 * i:off + 14 + 12 * i])
        f = TYPES[typ]
        size = struct.calcsize(e + f) * cnt if f != "s" else cnt
        raw = val if size <= 4 else data[struct.unpack(e + "I", val)[0]:][:size]
        if f == "s":
            tags[tag] = raw[:cnt]
        else:
            v = struct.unpack(e + f * cnt, raw[:size])
            tags[tag] = v
    return e, tags


def lzw_decode(data):
    out = bytearray()
    table = [bytes([i]) for i in range(256)] + [b"", b""]
    pos, width, prev, nbits = 0, 9, None, len(data) * 8
    while pos + width <= nbits:
        chunk = int.from_bytes(data[pos >> 3:(pos >> 3) + 3].ljust(3, b"\0"), "big")
        code = (chunk >> (24 - (pos & 7) - width)) & ((1 << width) - 1)
        pos += width
        if code == 256:
            table, width, prev = table[:258], 9, None
            continue
        if code == 257:
            break
        if prev is None:
            entry = table[code]
        elif code < len(table):
            entry = table[code]
            table.append(prev + entry[:1])
        else:
            entry = prev + prev[:1]
            table.append(entry)
        out += entry
        prev = entry
        if len(table) + 1 >= (1 << width) and width < 12:
            width += 1
    return bytes(out)


def read_tiff(path):
    """(array H x W x spp, tags): float32 or uint16 as stored."""
    data = open(path, "rb").read()
    e, t = tiff_tags(data)
    w, h = t[256][0], t[257][0]
    bps, spp = t[258][0], t[277][0]
    fmt = t.get(339, (1,))[0]
    comp, pred = t.get(259, (1,))[0], t.get(317, (1,))[0]
    rps = t.get(278, (h,))[0]
    raw = b""
    for off, cnt in zip(t[273], t[279]):
        s = data[off:off + cnt]
        raw += lzw_decode(s) if comp == 5 else s
    nb = bps // 8
    rowlen = w * spp * nb
    rows = []
    for y in range(h):
        r = np.frombuffer(raw[y * rowlen:(y + 1) * rowlen], dtype=np.uint8).copy()
        if pred == 3:
            r = r.reshape(-1, spp)
            r = np.cumsum(r, axis=0, dtype=np.uint64).astype(np.uint8).reshape(-1)
            planes = r.reshape(nb, w * spp)  # most significant byte first
            r = np.ascontiguousarray(planes.T).view(">f%d" % nb).reshape(-1).astype(np.float32)
        else:
            dt = np.dtype(e + ("f" if fmt == 3 else "u") + str(nb))
            r = np.frombuffer(r.tobytes(), dtype=dt).copy()
            if pred == 2:
                r = np.cumsum(r.reshape(-1, spp), axis=0, dtype=np.uint64).astype(
                    np.uint64) % (1 << bps)
                r = r.astype(dt).reshape(-1)
        rows.append(r.reshape(w, spp))
    assert rps > 0
    return np.stack(rows), t


def read_png(data):
    """H x W x 3 uint8 of an 8-bit RGB(A) PNG's bytes."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    pos, idat, w = 8, b"", 0
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, ctype, _, _, inter = struct.unpack(">IIBBBBB", body)
            assert depth == 8 and ctype in (2, 6) and inter == 0, (depth, ctype, inter)
            ch = 3 if ctype == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = zlib.decompress(idat)
    stride = w * ch
    out = np.zeros((h, stride), dtype=np.int32)
    prev = np.zeros(stride, dtype=np.int32)
    for y in range(h):
        f = raw[y * (stride + 1)]
        cur = np.frombuffer(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)], np.uint8).astype(np.int32)
        if f == 0:
            row = cur
        elif f == 2:
            row = (cur + prev) & 255
        else:
            row = np.zeros(stride, dtype=np.int32)
            for i in range(stride):
                a = row[i - ch] if i >= ch else 0
                b = prev[i]
                c = prev[i - ch] if i >= ch else 0
                if f == 1:
                    p = a
                elif f == 3:
                    p = (a + b) // 2
                else:
                    pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                    p = a if pa <= pb and pa <= pc else b if pb <= pc else c
                row[i] = (cur[i] + p) & 255
        out[y] = row
        prev = row
    return out.reshape(h, w, ch)[:, :, :3].astype(np.uint8)
