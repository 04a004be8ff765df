"""Read the cubes written by test_envi_spectral with Spectral Python and compare.

Exit 0 when every value and header field matches, 1 otherwise, 77 when
python3-spectral (or numpy) is not installed."""
import sys

try:
    import numpy as np
    import spectral.io.envi as envi
except ImportError as e:
    print("SKIP: python3-spectral not available: %s" % e)
    sys.exit(77)

S, L, B = 7, 5, 4
d = sys.argv[1]
failures = []


def expected():
    y, x, b = np.meshgrid(np.arange(L), np.arange(S), np.arange(B), indexing="ij")
    return ((x * 7 + y * 13 + b * 31) / 1000.0).astype(np.float32)


def check(cond, what):
    if not cond:
        failures.append(what)


for name, scaled in (("bsq_f32", False), ("bil_f32", False), ("bip_u16", True)):
    img = envi.open("%s/%s.hdr" % (d, name))
    a = np.asarray(img.load())  # applies 'reflectance scale factor'
    check(a.shape == (L, S, B), "%s: shape %s" % (name, a.shape))
    err = np.max(np.abs(a - expected()))
    check(err < 1e-6, "%s: values differ by %g" % (name, err))
    check(list(img.bands.centers) == [400.0, 405.0, 410.0, 415.0], "%s: wavelengths %s" % (name, img.bands.centers))
    check(img.bands.band_unit == "Nanometers", "%s: units %s" % (name, img.bands.band_unit))
    check(img.metadata.get("band names") == ["R", "G", "B", "NIR"], "%s: band names" % name)
    if scaled:
        raw = np.asarray(img.open_memmap()[2, 3])  # row 2, column 3: stored integers
        want = np.array([3 * 7 + 2 * 13 + b * 31 for b in range(B)])
        check(raw.dtype == np.uint16 and np.array_equal(raw, want), "%s: raw pixel %s" % (name, raw))

img = envi.open("%s/labels.hdr" % d)
m = img.metadata
check(m.get("file type") == "ENVI Classification", "labels: file type %s" % m.get("file type"))
check(m.get("classes") == "3", "labels: classes %s" % m.get("classes"))
check(m.get("class names") == ["unclassified", "gold", "shakudo"], "labels: names %s" % m.get("class names"))
check([int(v) for v in m.get("class lookup", [])] == [0, 0, 0, 255, 200, 0, 40, 30, 60], "labels: lookup")
lab = np.asarray(img.load(dtype=np.uint8))[:, :, 0]
want = (np.arange(6 * 3) % 3).reshape(3, 6)
check(np.array_equal(lab, want), "labels: values\n%s" % lab)

for f in failures:
    print("FAIL:", f)
print("spectral python read %s: %s" % (d, "ok" if not failures else "%d failures" % len(failures)))
sys.exit(1 if failures else 0)
