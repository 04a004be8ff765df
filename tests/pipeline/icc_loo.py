#!/usr/bin/env python3
"""camera.icc held out, recomputed from camera.ti3 outside kogei: for each patch, the
least-squares 3x3 matrix XYZ = M RGB fitted on the other patches, and the CIEDE2000
(D50) of the held-out patch. Compares mean and max with process.json's
calibration.camera_icc.loo_de00_mean/max (within 0.01). With --argyll, the same
leave-one-out with ArgyllCMS's colprof -am (shaper/matrix) and xicclu, printed beside.
usage: icc_loo.py PROCESS_JSON CAMERA_TI3 [--argyll TMPDIR]"""
import json, math, os, re, subprocess, sys

D50 = (96.42, 100.0, 82.49)


def lab(xyz):
    f = lambda t: t ** (1 / 3) if t > 216 / 24389 else (24389 / 27 * t + 16) / 116
    fx, fy, fz = (f(xyz[i] / D50[i]) for i in range(3))
    return 116 * fy - 16, 500 * (fx - fy), 200 * (fy - fz)


def de00(l1, l2):
    L1, a1, b1 = l1
    L2, a2, b2 = l2
    cb = (math.hypot(a1, b1) + math.hypot(a2, b2)) / 2
    g = 0.5 * (1 - math.sqrt(cb ** 7 / (cb ** 7 + 25 ** 7)))
    a1p, a2p = (1 + g) * a1, (1 + g) * a2
    c1, c2 = math.hypot(a1p, b1), math.hypot(a2p, b2)
    h1 = math.degrees(math.atan2(b1, a1p)) % 360
    h2 = math.degrees(math.atan2(b2, a2p)) % 360
    dh = 0 if c1 * c2 == 0 else (h2 - h1 - 360 if h2 - h1 > 180 else
                                 h2 - h1 + 360 if h2 - h1 < -180 else h2 - h1)
    dH = 2 * math.sqrt(c1 * c2) * math.sin(math.radians(dh / 2))
    lb, cbp = (L1 + L2) / 2, (c1 + c2) / 2
    if c1 * c2 == 0:
        hb = h1 + h2
    elif abs(h1 - h2) <= 180:
        hb = (h1 + h2) / 2
    else:
        hb = (h1 + h2 + 360) / 2 if h1 + h2 < 360 else (h1 + h2 - 360) / 2
    t = (1 - 0.17 * math.cos(math.radians(hb - 30)) + 0.24 * math.cos(math.radians(2 * hb))
         + 0.32 * math.cos(math.radians(3 * hb + 6)) - 0.20 * math.cos(math.radians(4 * hb - 63)))
    dth = 30 * math.exp(-((hb - 275) / 25) ** 2)
    rc = 2 * math.sqrt(cbp ** 7 / (cbp ** 7 + 25 ** 7))
    sl = 1 + 0.015 * (lb - 50) ** 2 / math.sqrt(20 + (lb - 50) ** 2)
    sc, sh = 1 + 0.045 * cbp, 1 + 0.015 * cbp * t
    rt = -math.sin(math.radians(2 * dth)) * rc
    dl, dc = L2 - L1, c2 - c1
    return math.sqrt((dl / sl) ** 2 + (dc / sc) ** 2 + (dH / sh) ** 2 + rt * (dc / sc) * (dH / sh))


def solve3(a, b):
    """x with a x = b, a 3x3 (Cramer)."""
    det = lambda m: (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                     - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                     + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))
    d = det(a)
    out = []
    for c in range(3):
        m = [row[:] for row in a]
        for r in range(3):
            m[r][c] = b[r]
        out.append(det(m) / d)
    return out


def fit(rows):
    ata = [[sum(r[0][i] * r[0][j] for r in rows) for j in range(3)] for i in range(3)]
    return [solve3(ata, [sum(r[0][i] * r[1][o] for r in rows) for i in range(3)]) for o in range(3)]


def read_ti3(path):
    text = open(path).read()
    fields = re.search(r"BEGIN_DATA_FORMAT\s+(.*?)\s+END_DATA_FORMAT", text, re.S).group(1).split()
    data = re.search(r"BEGIN_DATA\s+(.*?)\s+END_DATA", text, re.S).group(1).strip().split("\n")
    ix = {f: i for i, f in enumerate(fields)}
    rows = []
    for line in data:
        v = line.split()
        rows.append(([float(v[ix["RGB_" + c]]) / 100 for c in "RGB"],
                     [float(v[ix["XYZ_" + c]]) for c in "XYZ"], v))
    return text, fields, rows


def main():
    pj, ti3 = sys.argv[1], sys.argv[2]
    ci = json.load(open(pj))["calibration"]["camera_icc"]
    text, fields, rows = read_ti3(ti3)
    errs = []
    for i, (rgb, xyz, _) in enumerate(rows):
        m = fit(rows[:i] + rows[i + 1:])
        got = [sum(m[o][k] * rgb[k] for k in range(3)) for o in range(3)]
        errs.append(de00(lab(got), lab(xyz)))
    mean, mx = sum(errs) / len(errs), max(errs)
    print("camera.icc leave-one-out dE00 (recomputed from camera.ti3): mean %.2f max %.2f; "
          "process.json: mean %.2f max %.2f" % (mean, mx, ci["loo_de00_mean"], ci["loo_de00_max"]))
    ok = abs(mean - ci["loo_de00_mean"]) < 0.01 and abs(mx - ci["loo_de00_max"]) < 0.01
    ok = ok and ci["loo_de00_mean"] >= ci["fit_de00_mean"] - 1e-9
    if len(sys.argv) > 4 and sys.argv[3] == "--argyll":
        tmp = sys.argv[4]
        head, rest = text.split("BEGIN_DATA\n", 1)
        tail = rest.split("END_DATA", 1)[1]
        aerr = []
        for i in range(len(rows)):
            keep = [" ".join(r[2]) for j, r in enumerate(rows) if j != i]
            h = re.sub(r"NUMBER_OF_SETS\s+\d+", "NUMBER_OF_SETS %d" % len(keep), head)
            open(os.path.join(tmp, "loo.ti3"), "w").write(h + "BEGIN_DATA\n" + "\n".join(keep) + "\nEND_DATA" + tail)
            subprocess.run(["colprof", "-am", "-ua", "-D", "loo", "loo"], cwd=tmp, check=True,
                           capture_output=True, timeout=60)
            rgb = rows[i][0]
            out = subprocess.run(["xicclu", "-ia", "-pl", "loo.icc"], cwd=tmp, capture_output=True,
                                 text=True, input="%f %f %f\n" % tuple(rgb), timeout=60).stdout
            m = re.search(r"([-\d.]+)\s+([-\d.]+)\s+([-\d.]+)\s+\[Lab\]", out)
            aerr.append(de00(tuple(float(x) for x in m.groups()), lab(rows[i][1])))
        print("ArgyllCMS colprof -am -ua, leave-one-out dE00: mean %.2f max %.2f"
              % (sum(aerr) / len(aerr), max(aerr)))
    if not ok:
        print("FAIL: camera.icc's leave-one-out in process.json does not match the recomputation")
    return 0 if ok else 1


sys.exit(main())
