#!/usr/bin/env python3
"""A manifest of kogei process in OpenSeadragon in a running headless Chromium, over the
Chrome DevTools Protocol (called by test_iiif.sh viewer, which starts and stops Chromium
and the image server).

usage: iiif_browser.py DevToolsActivePort VIEWER_URL SHOT_PREFIX
The viewer page (iiif_viewer.html) loads the manifest, the access copy through the
image service's info.json and tiles, and the label map as a layer. Checked: both
layers load, tiles come from the image server (/iiif/) with status 200, the
screenshot is not blank (its pixels vary, and the image covers part of the view),
turning the label layer off changes the picture and on again restores it, and no
console error.
"""
import base64
import json
import struct
import sys
import time
import zlib

from cdp import Cdp

failures = []


def fail(msg):
    failures.append(msg)
    print("FAIL: " + msg)


def png_rgb(data):
    """A PNG of 8-bit RGB or RGBA, non-interlaced (what Chromium writes), as rows of
    (r, g, b) bytes: width, height, bytearray."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    at, idat = 8, b""
    while at < len(data):
        (n,) = struct.unpack(">I", data[at:at + 4])
        kind = data[at + 4:at + 8]
        body = data[at + 8:at + 8 + n]
        if kind == b"IHDR":
            w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        at += 12 + n
    if depth != 8 or ctype not in (2, 6) or interlace:
        raise ValueError("PNG of depth %d, colour type %d" % (depth, ctype))
    bpp = 3 if ctype == 2 else 4
    raw = zlib.decompress(idat)
    stride = w * bpp
    out = bytearray(h * w * 3)
    prev = bytearray(stride)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        for x in range(w):
            out[(y * w + x) * 3:(y * w + x) * 3 + 3] = line[x * bpp:x * bpp + 3]
        prev = line
    return w, h, out


def stats(px):
    n = len(px)
    mean = sum(px) / n
    var = sum((v - mean) ** 2 for v in px[::7]) / len(px[::7])
    lit = sum(1 for i in range(0, n, 3) if px[i] + px[i + 1] + px[i + 2] > 30) / (n // 3)
    return mean, var ** 0.5, lit


def main():
    port_file, url, shot = sys.argv[1:4]
    with open(port_file) as f:
        port, path = f.read().split()[:2]
    cdp = Cdp("ws://127.0.0.1:%s%s" % (port, path))
    target = cdp.call("Target.createTarget", {"url": "about:blank"})["targetId"]
    session = cdp.call("Target.attachToTarget",
                       {"targetId": target, "flatten": True})["sessionId"]
    for domain in ("Page", "Network", "Log", "Runtime"):
        cdp.call(domain + ".enable", session=session)
    cdp.call("Emulation.setDeviceMetricsOverride",
             {"width": 800, "height": 600, "deviceScaleFactor": 1, "mobile": False},
             session=session)
    nav = cdp.call("Page.navigate", {"url": url}, session=session)
    if nav.get("errorText"):
        fail("navigation: " + nav["errorText"])

    def evaluate(expr):
        r = cdp.call("Runtime.evaluate", {"expression": expr, "returnByValue": True},
                     session=session)
        if "exceptionDetails" in r:
            raise RuntimeError("evaluate: %s" % json.dumps(r["exceptionDetails"])[:300])
        return r["result"].get("value")

    # both layers added and every tile drawn
    state = None
    deadline = time.time() + 60
    while time.time() < deadline:
        state = json.loads(evaluate("""JSON.stringify({ready: window.kg && window.kg.ready,
            error: window.kg && window.kg.error, layers: window.kg && window.kg.layers,
            loaded: !!(window.kg && window.kg.ready && window.kg.base.getFullyLoaded()
                       && window.kg.overlay.getFullyLoaded()),
            service: window.kg && window.kg.service, label: window.kg && window.kg.label})"""))
        if state.get("error") or state.get("loaded"):
            break
        time.sleep(0.2)
    print("viewer: %r" % state)
    if state.get("error"):
        fail("the viewer: %s" % state["error"])
        return
    if not state.get("loaded") or state.get("layers") != 2:
        fail("the viewer did not load both layers in 60 s: %r" % state)
        return
    time.sleep(0.5)

    def screenshot(name):
        data = base64.b64decode(cdp.call("Page.captureScreenshot", {"format": "png"},
                                         session=session)["data"])
        open("%s_%s.png" % (shot, name), "wb").write(data)
        w, h, px = png_rgb(data)
        return w, h, px

    w, h, on = screenshot("labels_on")
    mean, sd, lit = stats(on)
    print("screenshot with labels %dx%d: mean %.1f, sd %.1f, %.0f %% not black"
          % (w, h, mean, sd, 100 * lit))
    if sd < 10 or lit < 0.2:
        fail("the screenshot looks blank (sd %.1f, %.0f %% not black)" % (sd, 100 * lit))
    evaluate("document.getElementById('labels').click()")
    time.sleep(0.8)
    _, _, off = screenshot("labels_off")
    mean2, sd2, lit2 = stats(off)
    diff = sum(abs(a - b) for a, b in zip(on[::5], off[::5])) / len(on[::5])
    print("screenshot without labels: mean %.1f, sd %.1f; mean difference %.1f"
          % (mean2, sd2, diff))
    if sd2 < 10:
        fail("the screenshot without labels looks blank (sd %.1f)" % sd2)
    if diff < 2:
        fail("turning the label layer off changed nothing (mean difference %.2f)" % diff)
    evaluate("document.getElementById('labels').click()")
    time.sleep(0.8)
    _, _, again = screenshot("labels_again")
    back = sum(abs(a - b) for a, b in zip(on[::5], again[::5])) / len(on[::5])
    print("labels on again: mean difference %.2f from the first" % back)
    if back > diff / 4:
        fail("turning the label layer on again did not restore it (%.2f)" % back)

    tiles = [e["params"]["response"] for e in cdp.events
             if e["method"] == "Network.responseReceived"
             and "/iiif/" in e["params"]["response"]["url"]]
    jpgs = [r for r in tiles if r["url"].endswith(".jpg")]
    print("%d responses from the image server, %d tiles" % (len(tiles), len(jpgs)))
    if not jpgs or any(r["status"] != 200 for r in tiles):
        fail("tiles from the image server: %r" % [(r["url"], r["status"]) for r in tiles])
    if not any(r["url"].endswith("/info.json") for r in tiles):
        fail("no info.json was requested")
    errors = [e["params"]["entry"]["text"] for e in cdp.events
              if e["method"] == "Log.entryAdded" and e["params"]["entry"]["level"] == "error"]
    if errors:
        fail("console errors: %r" % errors[:5])


if __name__ == "__main__":
    try:
        main()
    except Exception as e:  # a protocol failure is the test's failure, said plainly
        fail("%s: %s" % (type(e).__name__, e))
    sys.exit(1 if failures else 0)
