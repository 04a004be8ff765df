#!/usr/bin/env python3
"""The console's live view in headless Chromium (bench/console_live.sh starts it):
for each sim camera, `kogei console` on 127.0.0.1, the page opened, and over SECONDS
the previews the page drew (kogeiStats.frames: previews decoded and drawn into the
canvas at an animation frame) and their latency (kogeiStats.latencies: from the
frame's delivery by the camera driver, the X-Kogei-Captured-Ms header, to the
animation frame that drew it; the page and the console share the machine's clock).
The server's CPU time per preview comes from GET /api/live's server_parts_ms.

  console_live.py --kogei KOGEI --devtools FILE --work DIR [--seconds S] [--shot PNG]
                  -o OUT.md"""
import argparse
import os
import sys
import time

here = os.path.dirname(os.path.abspath(__file__))
tests = os.path.join(here, "..", "tests")
sys.path.insert(0, os.path.join(tests, "console"))
sys.path.insert(0, os.path.join(tests, "pipeline"))
from console_browser import Page  # noqa: E402
from console_common import Console  # noqa: E402
from report_browser import Cdp  # noqa: E402

CAMERAS = [  # (label, URI); the sim's default 30 frames/s
    ("1024 x 768 Bayer RGGB 12-bit",
     "sim:?format=bayer_rggb12&fullwell=20000&read=5&width=1024&height=768"),
    ("4000 x 3000 (12 Mpix) Bayer RGGB 12-bit",
     "sim:?format=bayer_rggb12&fullwell=20000&read=5&width=4000&height=3000"),
]


def pct(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(q * len(v)))] if v else float("nan")


def measure(cdp, kogei, work, label, uri, seconds, shot=None):
    c = Console(kogei, os.path.join(work, "S%d" % int(time.time() * 1000)), [uri])
    p = Page(cdp)
    try:
        p.go(c.url)
        if not p.wait("kogeiStats.frames >= 5", 60):
            raise RuntimeError("%s: the page showed no previews in 60 s" % label)
        time.sleep(2)  # past the start
        f0, n0, t0 = p.js("kogeiStats.frames"), p.js("kogeiStats.latencies.length"), time.time()
        load0 = os.getloadavg()[0]
        parts, samples = {}, 0
        while time.time() - t0 < seconds:
            time.sleep(0.5)
            _, live = c.json("GET", "/api/live")
            for k, v in live.get("server_parts_ms", {}).items():
                parts[k] = parts.get(k, 0) + v
            samples += 1
        f1, t1 = p.js("kogeiStats.frames"), time.time()
        lat = p.js("kogeiStats.latencies.slice(%d)" % n0) if f1 > f0 else []
        if shot:  # the page as it runs, its own rate and latency in the status line
            p.shot(shot)
        load1 = os.getloadavg()[0]
        mean = {k: v / max(samples, 1) for k, v in parts.items()}
        return {
            "label": label, "uri": uri,
            "preview": "%d x %d" % (live["preview_width"], live["preview_height"]),
            "image": live.get("image_type", "?"),
            "fps": (f1 - f0) / (t1 - t0), "seconds": t1 - t0, "frames": f1 - f0,
            "lat50": pct(lat, 0.5), "lat95": pct(lat, 0.95),
            "cpu": (mean.get("cpu_camera", float("nan")),
                    mean.get("cpu_capture", float("nan")) - mean.get("cpu_camera", 0),
                    mean.get("cpu_publish", float("nan"))),
            "load": (load0 + load1) / 2,
        }
    finally:
        p.close()
        c.stop()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kogei", required=True)
    ap.add_argument("--devtools", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--seconds", type=float, default=20)
    ap.add_argument("-o", "--out", required=True)
    ap.add_argument("--shot", help="a screenshot of the page of the first camera, at the "
                    "end of its measurement")
    a = ap.parse_args()
    with open(a.devtools) as f:
        port, path = f.read().split()[:2]
    cdp = Cdp("ws://127.0.0.1:%s%s" % (port, path))
    rows = [measure(cdp, a.kogei, a.work, label, uri, a.seconds, a.shot if i == 0 else None)
            for i, (label, uri) in enumerate(CAMERAS)]
    lines = [
        "# The console's live view in headless Chromium",
        "",
        "`bench/console_live.sh %s OUT.md %g`, %s, %d online CPUs. Previews drawn by the "
        "page per second over %g s, their latency from the frame's delivery by the camera "
        "driver to the animation frame that drew it, and the console's CPU time per "
        "preview (mean of its samples): the sim camera's synthesis, binning and focus, "
        "display and encoding." % (a.kogei, a.seconds, time.strftime("%Y-%m-%d %H:%M UTC",
                                   time.gmtime()), os.cpu_count(), a.seconds),
        "",
        "| camera | preview | page previews/s | latency median / p95 ms | console CPU ms "
        "per preview: camera, bin + focus, display + encode | load average |",
        "|---|---|--:|--:|--:|--:|",
    ]
    for r in rows:
        lines.append("| %s | %s %s | %.1f | %.0f / %.0f | %.1f, %.1f, %.1f | %.1f |" % (
            r["label"], r["preview"], r["image"].replace("image/", ""), r["fps"], r["lat50"],
            r["lat95"], r["cpu"][0], r["cpu"][1], r["cpu"][2], r["load"]))
    tmp = a.out + ".tmp"
    with open(tmp, "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(tmp, a.out)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
