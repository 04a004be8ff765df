#!/usr/bin/python3
"""An independent reading of a PLY file, for tests/ply/test_ply_assimp.c.

Written from the PLY description (Turk 1994), sharing nothing with render/ply.c: ASCII
data are taken one element per line (blank lines ignored), binary data are walked
with struct. Prints

    ELEMENT NAME DECLARED FOUND     one per element: complete instances in the data
    VERTEX_PROPERTIES NAME...       the vertex element's property names
    TRIANGLES T DEGENERATE D        fan triangulation of the face element's index
                                    list: n indices give n-2 triangles, n < 3 none
    INDEXSUM S                      sum of the vertex indices of those triangles
    BOUNDS x0 y0 z0 x1 y1 z1        bounds of the vertex positions (when any)
    STATUS ok | STATUS short        whether the data hold every declared instance
"""
import struct
import sys

CODES = {"char": "b", "int8": "b", "uchar": "B", "uint8": "B", "short": "h", "int16": "h",
         "ushort": "H", "uint16": "H", "int": "i", "int32": "i", "uint": "I", "uint32": "I",
         "float": "f", "float32": "f", "double": "d", "float64": "d"}


def read_header(data):
    end = data.index(b"end_header")
    nl = data.find(b"\n", end)
    body = data[nl + 1:] if nl >= 0 else b""
    fmt, elements = None, []
    for raw in data[:end].split(b"\n")[1:]:
        words = raw.decode("latin-1").split()
        if not words:
            continue
        if words[0] == "format":
            fmt = words[1]
        elif words[0] == "element":
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements:
            elements[-1][2].append(words[1:])
    return fmt, elements, body


def ascii_instances(body, elements):
    lines = [l.split() for l in body.split(b"\n") if l.strip()]
    at = 0
    for name, count, props in elements:
        got = []
        for tokens in lines[at:at + count]:
            rec, pos = [], 0
            for p in props:
                if p[0] == "list":
                    n = int(tokens[pos]) if pos < len(tokens) else 0
                    rec.append([float(t) for t in tokens[pos + 1:pos + 1 + n]])
                    pos += 1 + n
                else:
                    rec.append(float(tokens[pos]))
                    pos += 1
            got.append(rec)
        at += len(got)
        yield name, count, props, got


def binary_instances(body, elements, order):
    pos = 0
    for name, count, props in elements:
        got = []
        for _ in range(count):
            rec, p0 = [], pos
            try:
                for p in props:
                    if p[0] == "list":
                        n = struct.unpack_from(order + CODES[p[1]], body, pos)[0]
                        pos += struct.calcsize(CODES[p[1]])
                        rec.append(list(struct.unpack_from(order + str(n) + CODES[p[2]],
                                                           body, pos)))
                        pos += n * struct.calcsize(CODES[p[2]])
                    else:
                        rec.append(struct.unpack_from(order + CODES[p[0]], body, pos)[0])
                        pos += struct.calcsize(CODES[p[0]])
            except struct.error:
                pos = p0
                break
            got.append(rec)
        yield name, count, props, got
        if len(got) < count:
            return


def main(path):
    fmt, elements, body = read_header(open(path, "rb").read())
    if fmt == "ascii":
        walk = ascii_instances(body, elements)
    else:
        walk = binary_instances(body, elements, "<" if fmt == "binary_little_endian" else ">")
    tris = degenerate = indexsum = 0
    bounds = None
    complete = True
    for name, count, props, got in walk:
        print("ELEMENT", name, count, len(got))
        complete &= len(got) == count
        names = [p[-1] for p in props]
        if name == "vertex":
            print("VERTEX_PROPERTIES", " ".join(names))
        if name == "vertex" and got and all(k in names for k in "xyz"):
            cols = [names.index(k) for k in "xyz"]
            lo = [min(r[c] for r in got) for c in cols]
            hi = [max(r[c] for r in got) for c in cols]
            bounds = lo + hi
        lists = [i for i, p in enumerate(props)
                 if p[0] == "list" and p[-1] in ("vertex_indices", "vertex_index")]
        if name == "face" and lists:
            for rec in got:
                v = rec[lists[0]]
                if len(v) < 3:
                    degenerate += 1
                for k in range(2, len(v)):
                    tris += 1
                    indexsum += int(v[0] + v[k - 1] + v[k])
    print("TRIANGLES", tris, "DEGENERATE", degenerate)
    print("INDEXSUM", indexsum)
    if bounds:
        print("BOUNDS", " ".join("%.9g" % b for b in bounds))
    print("STATUS", "ok" if complete else "short")


if __name__ == "__main__":
    main(sys.argv[1])
