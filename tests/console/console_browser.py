#!/usr/bin/env python3
"""The console in headless Chromium over the Chrome DevTools Protocol (started by
test_console_browser.sh): the live view updates with the sim camera, the clipping
overlay paints a saturated scene red, the chart check finds the simulated chart, a
dark capture started from the page lands in session.json, the session view lists it,
a page on a non-default address without its token is refused, and path traversal from
the page is refused. Screenshots of each view go to SHOTDIR.

usage: console_browser.py KOGEI DevToolsActivePort WORKDIR SHOTDIR CHART.tif"""
import base64
import json
import os
import sys
import time

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
sys.path.insert(0, os.path.join(here, "..", "pipeline"))
from console_common import Console, check, fail, failures  # noqa: E402
from report_browser import Cdp, png_decoded_size  # noqa: E402

CAM = "format=bayer_rggb12&fullwell=20000&read=5&serial=site-1"


class Page:
    def __init__(self, cdp):
        self.cdp = cdp
        self.target = cdp.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.s = cdp.call("Target.attachToTarget",
                          {"targetId": self.target, "flatten": True})["sessionId"]
        for d in ("Page", "Runtime"):
            cdp.call(d + ".enable", session=self.s)
        cdp.call("Emulation.setDeviceMetricsOverride",
                 {"width": 1480, "height": 900, "deviceScaleFactor": 1, "mobile": False},
                 session=self.s)

    def go(self, url):
        self.cdp.events.clear()
        nav = self.cdp.call("Page.navigate", {"url": url}, session=self.s)
        check(not nav.get("errorText"), "navigation to %s: %s" % (url, nav.get("errorText")))
        check(self.cdp.wait_event("Page.loadEventFired", 30) is not None, "%s loads" % url)

    def js(self, expr, timeout=30):
        r = self.cdp.call("Runtime.evaluate", {"expression": expr, "returnByValue": True,
                                               "awaitPromise": True},
                          session=self.s, timeout=timeout)
        if "exceptionDetails" in r:
            raise RuntimeError("%s: %s" % (expr[:80], r["exceptionDetails"]))
        return r["result"].get("value")

    def wait(self, expr, timeout=20):
        deadline = time.time() + timeout
        while time.time() < deadline:
            v = self.js(expr)
            if v:
                return v
            time.sleep(0.1)
        return None

    def shot(self, path):
        data = base64.b64decode(self.cdp.call("Page.captureScreenshot", {"format": "png"},
                                              session=self.s, timeout=60)["data"])
        with open(path, "wb") as f:
            f.write(data)
        try:
            png_decoded_size(data)
        except Exception as e:  # noqa: BLE001
            fail("screenshot %s: %s" % (path, e))

    def errors(self):
        for e in self.cdp.events:
            if e["method"] == "Runtime.exceptionThrown":
                fail("exception in the page: %s" % json.dumps(e["params"])[:300])

    def close(self):
        self.cdp.call("Target.closeTarget", {"targetId": self.target})


# clipping red as drawn from the JPEG preview (within its compression error)
RED = """(() => { const c = document.getElementById('live');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; let n = 0;
  for (let i = 0; i < d.length; i += 4) if (d[i] > 235 && d[i+1] < 20 && d[i+2] < 20) n++;
  return n / (d.length / 4); })()"""
HASH = """(() => { const c = document.getElementById('live');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; let h = 0;
  for (let i = 0; i < d.length; i += 7) h = (h * 31 + d[i]) >>> 0; return h; })()"""


def select_camera(p, i):
    frames = p.js("kogeiStats.frames")
    p.js("(() => { const s = document.getElementById('camera'); s.value = '%d';"
         " s.dispatchEvent(new Event('change')); return 1; })()" % i)
    # previews taken after the switch: give the camera a few frames
    return p.wait("kogeiStats.frames >= %d" % (frames + 4), 20)


def main():
    kogei, devtools, work, shots, chart = sys.argv[1:6]
    with open(devtools) as f:
        port, path = f.read().split()[:2]
    cdp = Cdp("ws://127.0.0.1:%s%s" % (port, path))
    session = os.path.join(work, "S")
    cams = ["sim:?" + CAM + "&width=1024&height=768",
            "sim:?" + CAM + "&width=1024&height=768&light=100",
            "sim:%s?%s" % (chart, CAM)]
    c = Console(kogei, session, cams, extra=["--layout", "cie-tcs-frame"])
    p = Page(cdp)
    try:
        p.go(c.url)
        # ---- live view: frames arrive, with new sequence numbers and new pixels ----
        check(p.wait("kogeiStats.frames >= 3", 20), "the live view shows 3 previews in 20 s")
        h1 = p.js(HASH)
        check(p.wait("kogeiStats.frames >= 6", 20), "the live view keeps updating")
        h2 = p.js(HASH)
        seqs = p.js("kogeiStats.sequences")
        check(len(set(seqs or [])) >= 2, "two different frame sequence numbers: %s" % seqs)
        check(h1 != h2, "the live image changes between previews (noise of the sim sensor)")
        check(p.js("document.getElementById('focus').textContent") not in ("", "–"),
              "a focus score is shown")
        # ---- the view (EV, peaking) goes to the console by POST /api/view ----
        p.js("(() => { const e = document.getElementById('ev'); e.value = '2';"
             " e.dispatchEvent(new Event('input')); const k = document.getElementById('peaking');"
             " k.checked = true; k.dispatchEvent(new Event('change')); return 1; })()")
        LIVE_VIEW = ("fetch('/api/live?after=0').then(r => r.json())"
                     ".then(j => j.ev === %s && j.peaking === %s)")
        check(p.wait(LIVE_VIEW % ("2", "true"), 20),
              "EV 2 and peaking set on the page reach the previews (POST /api/view)")
        p.js("(() => { const e = document.getElementById('ev'); e.value = '0';"
             " e.dispatchEvent(new Event('input')); const k = document.getElementById('peaking');"
             " k.checked = false; k.dispatchEvent(new Event('change')); return 1; })()")
        check(p.wait(LIVE_VIEW % ("0", "false"), 20), "EV 0 and peaking off again")
        normal_red = p.js(RED)
        p.shot(os.path.join(shots, "console-live.png"))
        # ---- clipping overlay on a saturated scene ----
        check(select_camera(p, 1), "previews after switching to the saturated camera")
        # the sim sensor opens at its auto exposure: a long one from the page saturates it
        p.js("document.getElementById('exposure').value = '20000';"
             " document.getElementById('apply').click(); 1")
        check(p.wait("/exposure20000\\.0 /.test(document.getElementById('readback')"
                     ".textContent)", 15), "the exposure set from the page is read back: %s" %
              p.js("document.getElementById('readback').textContent"))
        frames = p.js("kogeiStats.frames")
        p.wait("kogeiStats.frames >= %d" % (frames + 3), 20)
        red = p.js(RED)
        check(red > 0.5 and red > normal_red + 0.3,
              "clipping overlay: %.1f %% red on the saturated scene, %.1f %% before" %
              (100 * red, 100 * normal_red))
        p.shot(os.path.join(shots, "console-clipping.png"))
        # ---- chart check ----
        check(select_camera(p, 2), "previews of the chart scene")
        p.js("kogeiShowView('chart'); document.getElementById('check').click(); 1")
        verdict = p.wait("(() => { const v = document.getElementById('verdict');"
                         " return /GO/.test(v.textContent) ? v.textContent : ''; })()", 30)
        check(verdict, "the chart check gives a verdict")
        found = p.js("(() => { const t = document.getElementById('chartinfo').textContent;"
                     " return /tags used: [1-9]/.test(t); })()")
        check(found, "the chart is found by its tags: %s" %
              p.js("document.getElementById('chartinfo').textContent"))
        time.sleep(0.5)
        p.shot(os.path.join(shots, "console-chart.png"))
        # ---- a dark capture from the page lands in session.json ----
        select_camera(p, 0)
        p.js("kogeiShowView('capture'); document.getElementById('kind').value = 'dark';"
             " document.getElementById('frames').value = '3';"
             " document.getElementById('cexposure').value = '5000';"
             " document.getElementById('start').click(); 1")
        man = None
        deadline = time.time() + 30
        while time.time() < deadline and not man:
            try:
                with open(os.path.join(session, "session.json")) as f:
                    m = json.load(f)
                if any(x["kind"] == "dark" for x in m["captures"]):
                    man = m
            except (OSError, ValueError):
                pass
            time.sleep(0.2)
        check(man is not None, "the dark capture started from the page is in session.json")
        check(p.wait("/clipped .* under-exposed/.test(document.getElementById('jobresult')"
                     ".textContent)", 15), "the capture's summary is shown")
        check(p.wait("kogeiStats.frames >= 2 && !/paused/.test(document.getElementById"
                     "('readback').textContent)", 15), "the live view resumes after the capture")
        p.shot(os.path.join(shots, "console-capture.png"))
        # ---- session view ----
        p.js("kogeiShowView('session'); 1")
        check(p.wait("document.querySelectorAll('#captures tbody tr').length >= 1", 10),
              "the session view lists the capture")
        p.shot(os.path.join(shots, "console-session.png"))
        # ---- path traversal from the page ----
        for bad in ("/session/%2e%2e/%2e%2e/etc/passwd", "/session/../../etc/passwd",
                    "/out/..%2f..%2fetc%2fpasswd"):
            st = p.js("fetch('%s').then(r => r.status)" % bad)
            check(st in (403, 404), "fetch %s from the page: %s" % (bad, st))
        p.errors()
    finally:
        p.close()
        c.stop()
    # ---- a non-default address: every request needs the token ----
    t = Console(kogei, os.path.join(work, "T"), [cams[0]], listen="127.0.0.2:0")
    p = Page(cdp)
    try:
        p.go(t.url)
        body = p.js("document.body.innerText")
        check("token" in (body or ""), "the page without its token is refused: %r" % body[:120])
        st = p.js("fetch('/api/state').then(r => r.status)")
        check(st == 403, "an API request without the token: %s" % st)
        p.go(t.url + "?token=" + t.token)
        check(p.wait("kogeiStats.frames >= 2", 20), "with the token the live view runs")
        p.errors()
    finally:
        p.close()
        t.stop()
    print("console-browser: %s" % ("FAIL (%d)" % len(failures) if failures else "ok"))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
