"""Read the files of test_spectral.c with Spectral Python (an independent ENVI
reader) and compare them with what kogei's own reader saw.

Usage: read_spectral.py DIR W H
DIR holds cube.hdr (f32 bsq), cube_bip.hdr (f32 bip), labels.hdr (classification)
and, from kogei's reader, expect_cube.f32 (W*H*61 floats, BIP) and expect_labels.u8.
"""
import sys

import numpy as np
import spectral.io.envi as envi

d, w, h = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
failures = 0


def check(cond, msg):
    global failures
    if not cond:
        print("FAIL:", msg)
        failures += 1


expect = np.fromfile(d + "/expect_cube.f32", dtype=np.float32).reshape(h, w, 61)
for name in ("cube", "cube_bip"):
    img = envi.open(d + "/" + name + ".hdr", d + "/" + name + ".img")
    arr = np.asarray(img.load(), dtype=np.float32)
    check(arr.shape == (h, w, 61), "%s: shape %s" % (name, arr.shape))
    wl = [float(x) for x in img.metadata["wavelength"]]
    check(wl == [400.0 + 5 * i for i in range(61)], "%s: wavelengths %s" % (name, wl[:3]))
    same = np.array_equal(np.isnan(arr), np.isnan(expect)) and np.array_equal(
        np.nan_to_num(arr), np.nan_to_num(expect))
    check(same, "%s: values differ from kogei's reader" % name)
    print("%s: %s, %d NaN values, identical to kogei's reader: %s"
          % (name, arr.shape, int(np.isnan(arr).sum()), same))

labels = envi.open(d + "/labels.hdr", d + "/labels.img")
lab = np.asarray(labels.open_memmap()).reshape(h, w)
check(lab.dtype == np.uint8, "labels: dtype %s, expected uint8" % lab.dtype)
expect_lab = np.fromfile(d + "/expect_labels.u8", dtype=np.uint8).reshape(h, w)
check(labels.metadata["file type"] == "ENVI Classification", "labels: file type")
names = labels.metadata["class names"]
check(names[0] == "unclassified" and len(names) == int(labels.metadata["classes"]),
      "labels: class names %s" % names)
check(len(labels.metadata["class lookup"]) == 3 * len(names), "labels: class lookup")
check(np.array_equal(lab, expect_lab), "labels differ from kogei's reader")
print("labels: classes %s, counts %s" % (names, np.bincount(lab.ravel()).tolist()))
sys.exit(1 if failures else 0)
