#!/usr/bin/env python3
"""The library's prediction uncertainty in camera RGB (the "model_rsd" of
fixtures/materials/default.json; method in fixtures/materials/README.md).

usage: material_uncertainty.py LIBRARY.json NK_DIR CAMERA.csv [CAMERA.csv ...]

NK_DIR holds published n,k tables (CSV wavelength_nm,n,k): M_<Source>.csv for the
metals Au, Ag, Cu, and AuAg_Au<x>Ag<y>_Rioux2014.csv for the Au-Ag alloys. For each
camera and light (CIE A, and D50 approximated by a 5003 K Planck spectrum: the spread
is a ratio, and the light's shape enters only through the band weights) and incidence
0, 30 and 60 degrees, the unpolarised Fresnel reflectance of every table is integrated
to camera RGB over 400-700 nm, and so is the library's own model of the metal
(optics/nk.c). Each RGB is divided by its level l = |RGB| / sqrt(3)
(the matcher fits the intensity, so an error common to the channels is absorbed; and
the matcher's systematic terms are relative to l^2, as the calibration residual's):
a metal's model_rsd per channel is the sd over its tables of RGB / l; the mixing rule's, from Rioux's alloys against the rule applied to
Rioux's pure metals, as dev / (4 c (1 - c)) RMS over the compositions. An alloy: its
RGB by the rule with each metal's tables in turn (the other metals at their tables'
mean), the sds of RGB / l added in quadrature over the metals (independent), and the
mixing rule's scaled by 2 (1 - sum c_i^2) (4 c (1 - c) for two metals).
A dielectric: n +- 0.05 with its body
reflectance. Reported per library material: the largest over cameras, lights and
angles. Prints JSON {name: [r, g, b]}. Standard
library only."""
import cmath, csv, glob, json, math, os, sys

WL = list(range(400, 701, 5))

def table(path):
    rows = []
    with open(path) as f:
        for r in csv.reader(f):
            try:
                rows.append((float(r[0]), float(r[1]), float(r[2])))
            except (ValueError, IndexError):
                pass
    rows.sort()
    def at(w):
        for i in range(1, len(rows)):
            if rows[i][0] >= w:
                a, b = rows[i - 1], rows[i]
                t = (w - a[0]) / (b[0] - a[0]) if b[0] > a[0] else 0
                return a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])
        raise ValueError("%s: no data at %g nm" % (path, w))
    return [at(w) for w in WL]

# The library's own models (optics/nk.c): Drude + 2 critical points, exp(-iwt).
DCP = {
    "Au": (1.1431, 1.3202e16, 1.0805e14, (0.26698, 3.0834), (-1.2371, -1.0968),
           (3.8711e15, 4.1684e15), (4.4642e14, 2.3555e15)),   # vial-laroche2008-dcp
    "Ag": (15.833, 1.3861e16, 4.5841e13, (1.0171, 15.797), (-0.93935, 1.8087),
           (6.6327e15, 9.2726e17), (1.6666e15, 2.3716e17)),   # vial-laroche2008-dcp
    "Cu": (1.8097, 1.3209e16, 1.4086e14, (0.54253, 5.4965), (-1.5611, 0.79163),
           (3.2858e15, 1.1316e16), (4.0476e14, 4.7327e15)),   # vial2008ch-dcp
}

def dcp(el):
    einf, wd, gd, A, phi, om, ga = DCP[el]
    out = []
    for wl in WL:
        w = 2 * math.pi * 299792458.0e9 / wl
        e = einf - wd * wd / (w * w + 1j * gd * w)
        for j in range(2):
            e += A[j] * om[j] * (cmath.exp(1j * phi[j]) / (om[j] - w - 1j * ga[j]) +
                                 cmath.exp(-1j * phi[j]) / (om[j] + w + 1j * ga[j]))
        N = cmath.sqrt(e)
        out.append((N.real, abs(N.imag)))
    return out

def fresnel(nk, theta):
    c = math.cos(theta); s2 = math.sin(theta) ** 2
    out = []
    for n, k in nk:
        N = complex(n, k)
        ct = cmath.sqrt(1 - s2 / (N * N))
        rs = (c - N * ct) / (c + N * ct)
        rp = (N * c - ct) / (N * c + ct)
        out.append(0.5 * (abs(rs) ** 2 + abs(rp) ** 2))
    return out

def planck(T):
    return [1 / ((w * 1e-9) ** 5 * (math.exp(1.4388e-2 / (w * 1e-9 * T)) - 1)) for w in WL]

def camera(path):
    rows = {}
    with open(path) as f:
        for r in csv.reader(f):
            try:
                rows[int(round(float(r[0])))] = [float(v) for v in r[1:4]]
            except (ValueError, IndexError):
                pass
    return [rows[w] for w in WL]

def rgb(R, cam, E):
    return [sum(R[i] * cam[i][c] * E[i] for i in range(len(WL))) for c in range(3)]

def chroma(v):
    """RGB over its level l = |RGB| / sqrt(3): the fitted intensity takes the level"""
    m = math.sqrt(sum(x * x for x in v) / 3)
    return [x / m for x in v]

def rsd(vals):
    """per channel: the sd over vals (readings in units of their level)"""
    out = []
    for c in range(3):
        v = [x[c] for x in vals]
        m = sum(v) / len(v)
        out.append(math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1)))
    return out

def interp(xs, ys, w):
    if w <= xs[0]:
        return ys[0]
    for i in range(1, len(xs)):
        if xs[i] >= w:
            t = (w - xs[i - 1]) / (xs[i] - xs[i - 1])
            return ys[i - 1] + t * (ys[i] - ys[i - 1])
    return ys[-1]

def main():
    lib, nkdir, cams = sys.argv[1], sys.argv[2], sys.argv[3:]
    mats = json.load(open(lib))["materials"]
    byname = {m["name"]: m for m in mats}
    metals = {}
    for el in ("Au", "Ag", "Cu"):
        metals[el] = [table(p) for p in sorted(glob.glob(os.path.join(nkdir, el + "_*.csv")))]
        metals[el].append(dcp(el))
    alloys = {}
    for p in glob.glob(os.path.join(nkdir, "AuAg_Au*Ag*_Rioux2014.csv")):
        au = int(os.path.basename(p).split("_")[1][2:].split("Ag")[0])
        alloys[au] = table(p)
    lights = [planck(2856), planck(5003)]
    out = {m["name"]: [0.0, 0.0, 0.0] for m in mats}
    keep = lambda name, r: out.__setitem__(name, [max(a, b) for a, b in zip(out[name], r)])
    for cp in cams:
        cam = camera(cp)
        for E in lights:
            for th in (0, 30, 60):
                t = math.radians(th)
                # every table's RGB; the metals' means
                sets = {el: [rgb(fresnel(x, t), cam, E) for x in v] for el, v in metals.items()}
                mean = {el: [sum(x[c] for x in v) / len(v) for c in range(3)]
                        for el, v in sets.items()}
                pure_au = rgb(fresnel(alloys[100], t), cam, E)
                pure_ag = rgb(fresnel(alloys[0], t), cam, E)
                acc, n = [0, 0, 0], 0
                for au, nk in alloys.items():
                    if au in (0, 100):
                        continue
                    c = au / 100
                    meas = chroma(rgb(fresnel(nk, t), cam, E))
                    mix = chroma([c * a + (1 - c) * b for a, b in zip(pure_au, pure_ag)])
                    for ch in range(3):
                        acc[ch] += ((meas[ch] - mix[ch]) / (4 * c * (1 - c))) ** 2
                    n += 1
                mixrule = [math.sqrt(a / n) for a in acc]
                for m in mats:
                    if m["kind"] == "metal":
                        keep(m["name"], rsd([chroma(x) for x in sets[m["nk"]["element"]]]))
                    elif m["kind"] == "alloy":
                        comp = [(byname[c["material"]]["nk"]["element"], c["fraction"])
                                for c in m["components"]]
                        tot = sum(f for _, f in comp)
                        comp = [(el, f / tot) for el, f in comp]
                        mixed = 2 * (1 - sum(f * f for _, f in comp))
                        # each metal's tables in turn, the others at their means
                        # (independent between metals: variances add)
                        var = [0, 0, 0]
                        for el, _ in comp:
                            v = []
                            for x in sets[el]:
                                v.append(chroma([sum(f * (x[ch] if e == el else mean[e][ch])
                                                     for e, f in comp) for ch in range(3)]))
                            var = [a + b * b for a, b in zip(var, rsd(v))]
                        keep(m["name"], [math.sqrt(a + (mixed * b) ** 2)
                                         for a, b in zip(var, mixrule)])
                    elif m["kind"] == "dielectric":
                        b = m["body"]
                        body = [interp(b["wavelength_nm"], b["reflectance"], w) for w in WL]
                        v = []
                        for nn in (m["n"] - 0.05, m["n"], m["n"] + 0.05):
                            F = fresnel([(nn, 0.0)] * len(WL), t)
                            v.append(rgb([f + (1 - f) * bb for f, bb in zip(F, body)], cam, E))
                        keep(m["name"], rsd([chroma(x) for x in v]))
    print(json.dumps({k: [round(x, 4) for x in v] for k, v in out.items()}))

if __name__ == "__main__":
    main()
