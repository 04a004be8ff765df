#!/usr/bin/env python3
"""Check an operator's report in a running headless Chromium over the Chrome
DevTools Protocol (called by report_browser.sh, which starts and stops Chromium).

usage: report_browser.py DevToolsActivePort REPORT.html SHOT.png MAX_HEIGHT
"""
import base64
import json
import urllib.parse
import os
import struct
import sys
import zlib

from cdp import Cdp

SECTIONS = ["summary", "calibration", "color-accuracy", "objects", "provenance",
            "warnings"]
failures = []


def fail(msg):
    failures.append(msg)
    print("FAIL: " + msg, file=sys.stderr)


def png_decoded_size(data):
    """Width, height of a PNG after checking its pixel data inflate to the size the
    header promises (8-bit RGB or RGBA, not interlaced)."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat, width = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            channels = {2: 3, 6: 4}.get(colour)
            if depth != 8 or channels is None or interlace:
                raise ValueError("unexpected PNG kind %d/%d/%d" % (depth, colour, interlace))
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = zlib.decompress(idat)
    if width is None or len(raw) != height * (1 + width * channels):
        raise ValueError("pixel data of %d bytes for %sx%s" % (len(raw), width, height))
    return width, height


def main():
    port_file, report, shot, max_height = sys.argv[1:5]
    max_height = int(max_height)
    with open(port_file) as f:
        port, path = f.read().split()[:2]
    cdp = Cdp("ws://127.0.0.1:%s%s" % (port, path))
    target = cdp.call("Target.createTarget", {"url": "about:blank"})["targetId"]
    session = cdp.call("Target.attachToTarget",
                       {"targetId": target, "flatten": True})["sessionId"]
    for domain in ("Page", "Network", "Log", "Runtime"):
        cdp.call(domain + ".enable", session=session)
    cdp.call("Emulation.setDeviceMetricsOverride",
             {"width": 1280, "height": 900, "deviceScaleFactor": 1, "mobile": False},
             session=session)
    cdp.events.clear()
    url = "file://" + os.path.abspath(report)
    nav = cdp.call("Page.navigate", {"url": url}, session=session)
    if nav.get("errorText"):
        fail("navigation: " + nav["errorText"])
    if not cdp.wait_event("Page.loadEventFired", 60):
        fail("the page did not finish loading in 60 s")
    cdp.drain(0.5)

    for e in cdp.events:
        m, p = e["method"], e.get("params", {})
        if m == "Network.requestWillBeSent":
            u = p["request"]["url"]
            if not (u.startswith("data:") or u.startswith("file:")):
                fail("request to %s" % u[:120])
        elif m == "Network.loadingFailed":
            fail("request failed: %s (%s)" % (p.get("errorText"), p.get("requestId")))
        elif m == "Log.entryAdded" and p["entry"]["level"] == "error":
            fail("console: %s" % p["entry"].get("text", "")[:300])
        elif m == "Runtime.consoleAPICalled" and p["type"] in ("error", "assert"):
            fail("console.%s: %s" % (p["type"], json.dumps(p.get("args"))[:300]))
        elif m == "Runtime.exceptionThrown":
            fail("exception: %s" % json.dumps(p.get("exceptionDetails"))[:300])

    probe = """JSON.stringify({
      headings: Array.from(document.querySelectorAll('section h2')).map(
        h => [h.parentElement.id, h.textContent]),
      images: Array.from(document.images).map(i => ({alt: i.alt,
        data: i.src.startsWith('data:image/png;base64,'), complete: i.complete,
        w: i.naturalWidth, h: i.naturalHeight})),
      legend: Array.from(document.querySelectorAll('table.legend td.name')).map(
        td => ({text: td.textContent, clipped: td.scrollWidth > td.clientWidth + 1,
                font: parseFloat(getComputedStyle(td).fontSize),
                shown: td.getBoundingClientRect().width > 0})),
      caveats: Array.from(document.querySelectorAll('p.caveat')).map(
        p => ({text: p.textContent, shown: p.getBoundingClientRect().height > 0})),
      heldout: Array.from(document.querySelectorAll('#heldout tbody tr')).map(
        tr => Array.from(tr.querySelectorAll('td')).map(td => td.textContent.trim())),
      links: Array.from(document.querySelectorAll('a[href]')).map(a => ({
        href: a.href, text: a.textContent, ctx: a.parentElement.textContent})),
      width: document.documentElement.scrollWidth,
      height: document.documentElement.scrollHeight})"""
    result = cdp.call("Runtime.evaluate", {"expression": probe, "returnByValue": True},
                      session=session)
    page = json.loads(result["result"]["value"])
    ids = [h[0] for h in page["headings"]]
    for s in SECTIONS:
        if s not in ids:
            fail("no <h2> in section %s (found %s)" % (s, ids))
    if not page["images"]:
        fail("no images in the page")
    for i, img in enumerate(page["images"]):
        if not img["data"]:
            fail("image %d (%s) is not an inline PNG" % (i, img["alt"]))
        if not img["complete"] or img["w"] <= 0 or img["h"] <= 0:
            fail("image %d (%s) did not decode" % (i, img["alt"]))

    # The legend, in HTML: every name whole (not clipped, no ellipsis), at a readable
    # size, and, when process.json is beside the report, every class of every object
    # named in full.
    for cell in page["legend"]:
        if cell["clipped"] or "\u2026" in cell["text"] or "..." in cell["text"]:
            fail("legend name %r is cut off" % cell["text"])
        if not cell["shown"] or cell["font"] < 11:
            fail("legend name %r is not readable (font %s px)" % (cell["text"], cell["font"]))
    pj = os.path.join(os.path.dirname(os.path.abspath(report)), "process.json")
    if os.path.exists(pj):
        names = {c["text"] for c in page["legend"]}
        with open(pj) as f:
            for o in json.load(f).get("objects", []):
                for c in o.get("classes", []):
                    if c["name"] not in names:
                        fail("class %r of %s is not named in full in a legend" %
                             (c["name"], o.get("capture")))

    # Beside the verdicts: the caveat, shown; when the record holds held-out colour
    # differences, the in-sample and held-out aggregates side by side, both numbers.
    if not any("not a certification" in c["text"] and c["shown"] for c in page["caveats"]):
        fail("no visible caveat 'not a certification' beside the verdicts")
    if os.path.exists(pj):
        with open(pj) as f:
            held = any(isinstance(x.get("de00_d50_heldout"), (int, float))
                       for x in json.load(f).get("calibration", {}).get("patches", []))
        if held:
            rows = page["heldout"]
            if len(rows) != 3:
                fail("held-out table: %d rows, expected mean, 90th percentile, maximum"
                     % len(rows))
            for r in rows:
                try:
                    a, b = float(r[0]), float(r[1])
                except (ValueError, IndexError):
                    fail("held-out table row %r: expected two numbers" % (r,))
                    continue
                if b < a:
                    fail("held-out table row %r: held-out below in-sample" % (r,))
    # The colour-managed files: each object's master.tif and the session's camera.icc
    # and camera.ti3 are links that resolve to the files beside the report, the
    # master's colour space named beside its link.
    outdir = os.path.dirname(os.path.abspath(report))
    def link_to(rel):
        url = "file://" + urllib.parse.quote(os.path.join(outdir, rel))
        found = [l for l in page["links"] if l["href"] == url]
        if not found:
            fail("no link to %s (%s) in the page" % (rel, url))
        elif not os.path.exists(urllib.parse.unquote(found[0]["href"][len("file://"):])):
            fail("link %s: no such file" % found[0]["href"])
        return found[0] if found else None
    if os.path.exists(pj):
        with open(pj) as f:
            pjson = json.load(f)
        for o in pjson.get("objects", []):
            m = o.get("master")
            if m:
                l = link_to(m["path"])
                if l and m["profile"] not in l["ctx"]:
                    fail("master %s: its colour space %r not named beside the link"
                         % (m["path"], m["profile"]))
        ci = pjson.get("calibration", {}).get("camera_icc")
        if ci:
            link_to(ci["path"])
            link_to(ci["ti3"])
    width, height = 1280, page["height"]
    if max_height > 0:
        height = min(height, max_height)
    height = min(height, 16000)
    shot_reply = cdp.call("Page.captureScreenshot", {
        "format": "png", "captureBeyondViewport": True,
        "clip": {"x": 0, "y": 0, "width": width, "height": height, "scale": 1}},
        session=session, timeout=60)
    data = base64.b64decode(shot_reply["data"])
    with open(shot, "wb") as f:
        f.write(data)
    try:
        w, h = png_decoded_size(data)
        if (w, h) != (width, height):
            fail("screenshot is %dx%d, expected %dx%d" % (w, h, width, height))
    except (ValueError, zlib.error) as e:
        fail("screenshot %s: %s" % (shot, e))
    cdp.call("Target.closeTarget", {"targetId": target})
    print("%s: %d sections, %d images, %d legend names, page %dx%d, screenshot %s "
          "%dx%d: %s" % (
        report, len(ids), len(page["images"]), len(page["legend"]), page["width"],
        page["height"], shot,
        width, height, "FAIL" if failures else "ok"))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
