#!/usr/bin/env python3
"""Measure the console's live preview on a large sim camera in headless Chromium:
the server's time per preview (frame to PNG) and the rate and latency the page
achieves (docs/console.md, "Performance"). Not a test: run it through
preview_rate.sh.

usage: preview_rate.py KOGEI DevToolsActivePort WORKDIR WIDTH HEIGHT SECONDS"""
import os
import sys
import time

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
from console_browser import Page  # noqa: E402
from console_common import Console  # noqa: E402
from report_browser import Cdp  # noqa: E402


def main():
    kogei, devtools, work, w, h, seconds = sys.argv[1:7]
    with open(devtools) as f:
        port, path = f.read().split()[:2]
    cdp = Cdp("ws://127.0.0.1:%s%s" % (port, path))
    cam = "sim:?format=bayer_rggb12&fullwell=20000&read=5&width=%s&height=%s" % (w, h)
    c = Console(kogei, os.path.join(work, "S"), [cam])
    p = Page(cdp)
    try:
        p.go(c.url)
        p.wait("kogeiStats.frames >= 2", 60)
        f0, t0 = p.js("kogeiStats.frames"), time.time()
        lat = []
        while time.time() - t0 < float(seconds):
            time.sleep(0.25)
            lat.append(p.js("kogeiStats.latencyMs"))
        f1, t1 = p.js("kogeiStats.frames"), time.time()
        _, live = c.json("GET", "/api/live")
        lat.sort()
        print("camera %s: %sx%s, preview %dx%d (binning %d)" % (cam, w, h,
              live["preview_width"], live["preview_height"], live["binning"]))
        print("server time per preview (frame to PNG): mean %.1f ms over %d previews" %
              (live["server_ms_mean"], f1))
        print("page: %.2f previews/s over %.0f s; latency (request to image shown) "
              "median %.0f ms" % ((f1 - f0) / (t1 - t0), t1 - t0, lat[len(lat) // 2]))
    finally:
        p.close()
        c.stop()


if __name__ == "__main__":
    main()
