#!/usr/bin/python3
"""Writes the seed corpus of fuzz_ply (see README.md). Run in this folder."""
import struct

CUBE_V = [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
CUBE_F = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]


def header(fmt, lines):
    return ("ply\nformat %s 1.0\ncomment fuzz seed\n" % fmt + "".join(l + "\n" for l in lines)
            + "end_header\n").encode()


def write(name, data):
    with open(name, "wb") as f:
        f.write(data)


# ASCII quads with normals, colours and materials, plus a skipped element.
lines = ["obj_info seed", "element vertex 8", "property float x", "property float y",
         "property float z", "property float nx", "property float ny", "property float nz",
         "property uchar red", "property uchar green", "property uchar blue",
         "property int material", "element edge 2", "property int vertex1",
         "property int vertex2", "element face 6", "property list uchar int vertex_indices",
         "property int material_index"]
body = "".join("%g %g %g 0 0 1 %d %d %d %d\n" % (x, y, z, 40 * x, 200, 255 * z, x) for x, y, z in CUBE_V)
body += "0 1\n2 3\n"
body += "".join("4 %d %d %d %d %d\n" % (f + (i,)) for i, f in enumerate(CUBE_F))
write("valid_ascii_cube.ply", header("ascii", lines) + body.encode())

# Binary, both byte orders: triangles, a polygon, a degenerate face, lists to skip.
for order, fmt in (("<", "binary_little_endian"), (">", "binary_big_endian")):
    lines = ["element vertex 5", "property list uchar float uv", "property double x",
             "property double y", "property double z", "property float red",
             "property float green", "property float blue", "element face 4",
             "property list ushort uint vertex_indices", "property short material"]
    body = b""
    for i, (x, y, z) in enumerate(CUBE_V[:5]):
        body += struct.pack(order + "B", i % 3) + struct.pack(order + "%df" % (i % 3), *[0.5] * (i % 3))
        body += struct.pack(order + "3d3f", x, y, z, 0.25, 0.5, 1.0)
    for face, mat in (((0, 1, 2), 1), ((0, 2, 3, 4), 2), ((1, 4), 3), ((4, 3, 2, 1, 0), 4)):
        body += struct.pack(order + "H%dIh" % len(face), len(face), *face, mat)
    write("valid_%s.ply" % ("le" if order == "<" else "be"), header(fmt, lines) + body)

# The layout the loader's fast paths take: float x y z and normals, triangles with a
# uchar count and int (LE) or uint (BE) indices.
for order, fmt, itype in (("<", "binary_little_endian", "int"), (">", "binary_big_endian", "uint")):
    lines = ["element vertex 8", "property float x", "property float y", "property float z",
             "property float nx", "property float ny", "property float nz", "element face 12",
             "property list uchar %s vertex_indices" % itype]
    body = b"".join(struct.pack(order + "6f", x, y, z, x - .5, y - .5, z - .5) for x, y, z in CUBE_V)
    for a, b, c, d in CUBE_F:
        body += struct.pack(order + "B3I", 3, a, b, c) + struct.pack(order + "B3I", 3, a, c, d)
    write("valid_plain_%s.ply" % ("le" if order == "<" else "be"), header(fmt, lines) + body)

# Every scalar type in one binary vertex element.
types = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double"]
codes = "bBhHiIfd"
lines = ["element vertex 2", "property int8 x", "property uint16 y", "property float64 z"]
lines += ["property %s p%d" % (t, i) for i, t in enumerate(types)]
lines += ["element face 1", "property list int8 int16 vertex_indices"]
body = b"".join(struct.pack("<bHd" + codes, i, i, 0.5, -1, 2, -3, 4, -5, 6, 7.5, 8.25)
                for i in range(2))
body += struct.pack("<b3h", 3, 0, 1, 1)
write("valid_types.ply", header("binary_little_endian", lines) + body)

# A vertex list the data leave out (assimp's issue623.ply), CRLF header.
write("valid_missing_list.ply",
      b"ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty float x\r\nproperty float y\r\n"
      b"property float z\r\nproperty list uchar uint vertex_indices\r\nend_header\r\n"
      b"0 0 0\r\n1 0 0\r\n0 1 0\r\n")

# Refusals, one per check.
base = ["element vertex 3", "property float x", "property float y", "property float z",
        "element face 1", "property list uchar int vertex_indices"]
verts = "0 0 0\n1 0 0\n0 1 0\n"
write("invalid_index.ply", header("ascii", base) + (verts + "3 0 1 3\n").encode())
write("invalid_nan.ply", header("ascii", base) + ("0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n").encode())
write("invalid_count.ply", header("ascii", base[:4] + ["element face 4294967295"] + base[5:])
      + (verts + "3 0 1 2\n").encode())
write("invalid_type.ply", header("ascii", ["element vertex 1", "property flaot x"]) + b"0\n")
write("invalid_truncated.ply",
      header("binary_big_endian", base) + struct.pack(">9f", 0, 0, 0, 1, 0, 0, 0, 1, 0)
      + struct.pack(">Bi", 3, 0))
write("invalid_no_end_header.ply", b"ply\nformat ascii 1.0\nelement vertex 0\n")
write("empty.ply", b"")
