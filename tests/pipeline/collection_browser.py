#!/usr/bin/env python3
"""Check a collection's index.html in a running headless Chromium over the Chrome
DevTools Protocol (test_collection_browser.sh starts and stops Chromium): nothing
loaded from outside the file, no console error (a script the page's
Content-Security-Policy refused is one), the table's rows as collection.json gives
them with text shown as written (no markup from the record), the thumbnails decoded,
and a click on a column's name sorting the rows by it, again the other way.

usage: collection_browser.py DevToolsActivePort INDEX.html COLLECTION.json
"""
import json
import os
import sys

from cdp import Cdp

failures = []


def fail(msg):
    failures.append(msg)
    print("FAIL: " + msg, file=sys.stderr)


def main():
    port_file, page, record = sys.argv[1:4]
    with open(port_file) as f:
        port, path = f.read().split()[:2]
    rec = json.load(open(record))
    cdp = Cdp("ws://127.0.0.1:%s%s" % (port, path))
    target = cdp.call("Target.createTarget", {"url": "about:blank"})["targetId"]
    session = cdp.call("Target.attachToTarget",
                       {"targetId": target, "flatten": True})["sessionId"]
    for domain in ("Page", "Network", "Log", "Runtime"):
        cdp.call(domain + ".enable", session=session)
    cdp.call("Emulation.setDeviceMetricsOverride",
             {"width": 1400, "height": 900, "deviceScaleFactor": 1, "mobile": False},
             session=session)
    cdp.events.clear()
    nav = cdp.call("Page.navigate", {"url": "file://" + os.path.abspath(page)},
                   session=session)
    if nav.get("errorText"):
        fail("navigation: " + nav["errorText"])
    if not cdp.wait_event("Page.loadEventFired", 60):
        fail("the page did not finish loading in 60 s")
    cdp.wait_event("kogei.never", 0.5)

    def evaluate(expr):
        r = cdp.call("Runtime.evaluate", {"expression": expr, "returnByValue": True},
                     session=session)
        if "exceptionDetails" in r:
            raise RuntimeError("evaluate: %s" % json.dumps(r["exceptionDetails"])[:300])
        return r["result"].get("value")

    rows_js = """JSON.stringify(Array.from(document.querySelectorAll('#collection tbody tr'))
        .map(tr => Array.from(tr.cells).map(td => td.textContent.trim())))"""
    header_js = """JSON.stringify(Array.from(document.querySelectorAll('#collection thead th'))
        .map(th => th.textContent.trim()))"""
    headers = json.loads(evaluate(header_js))
    rows = json.loads(evaluate(rows_js))
    col = {h: i for i, h in enumerate(headers)}
    for want in ("Entry", "Object", "Accession", "Status", "Warnings", "Conformance",
                 "Thumbnail", "Report"):
        if want not in col:
            fail("no column %r (columns %r)" % (want, headers))
    de_col = [h for h in headers if h.startswith("ΔE")]
    if not de_col:
        fail("no ΔE00 column (columns %r)" % headers)
        return
    # the rows: one per object of a done entry, one per entry without objects
    expect = []
    for e in rec["entries"]:
        if e["objects"]:
            for o in e["objects"]:
                expect.append((e["name"], o["name"], o["accession"] or "-", e["status"],
                               str(len(o["warnings"]))))
        else:
            expect.append((e["name"], "-", e["meta"].get("accession", "-"), e["status"], "-"))
    got = [(r[col["Entry"]], r[col["Object"]], r[col["Accession"]],
            r[col["Status"]].split()[0] if r[col["Status"]] else "", r[col["Warnings"]])
           for r in rows]
    if 'Z-9, lot "b"' not in [x[2] for x in expect]:
        fail("the quoted accession did not reach collection.json: %r" % [x[2] for x in expect])
    if got != expect:
        fail("rows %r, expected %r" % (got, expect))
    for e in rec["entries"]:
        if e["status"] == "failed":
            if not any(e["reason"] in r[col["Status"]] for r in rows):
                fail("the reason of %s is not shown" % e["name"])
    if evaluate("document.querySelectorAll('#collection tbody td *:not(div):not(img):not(a)').length"):
        fail("markup from the record became elements in the table")
    imgs = json.loads(evaluate("""JSON.stringify(Array.from(document.images).map(i => ({
        data: i.src.startsWith('data:image/png;base64,'), w: i.naturalWidth})))"""))
    ndone = sum(len(e["objects"]) for e in rec["entries"])
    if len(imgs) != ndone or not all(i["data"] and i["w"] > 0 for i in imgs):
        fail("thumbnails %r, expected %d decoded data: images" % (imgs, ndone))

    def click(header):
        box = json.loads(evaluate("""(() => {const b = Array.from(document.querySelectorAll(
            '#collection thead th')).find(th => th.textContent.trim() === %s)
            .querySelector('button').getBoundingClientRect();
            return JSON.stringify([b.x + b.width / 2, b.y + b.height / 2]);})()"""
                                  % json.dumps(header)))
        for t in ("mousePressed", "mouseReleased"):
            cdp.call("Input.dispatchMouseEvent", {"type": t, "x": box[0], "y": box[1],
                                                  "button": "left", "clickCount": 1},
                     session=session)
        return json.loads(evaluate(rows_js))

    acc = [r[col["Accession"]] for r in click("Accession")]
    if acc != sorted(acc, key=lambda s: s.lower()) or acc == [x[2] for x in expect]:
        fail("a click on Accession: %r, expected them sorted (and not the list's order %r)"
             % (acc, [x[2] for x in expect]))
    acc2 = [r[col["Accession"]] for r in click("Accession")]
    if acc2 != list(reversed(acc)):
        fail("a second click on Accession: %r, expected %r" % (acc2, list(reversed(acc))))
    de = [r[col[de_col[0]]] for r in click(de_col[0])]
    nums = [float(x) for x in de if x != "-"]
    if nums != sorted(nums) or (de and "-" in de and de[-1] != "-"):
        fail("a click on %s: %r, expected numbers ascending, none last" % (de_col[0], de))

    for e in cdp.events:
        m, p = e["method"], e.get("params", {})
        if m == "Network.requestWillBeSent":
            u = p["request"]["url"]
            if not (u.startswith("data:") or u.startswith("file:")):
                fail("request to %s" % u[:120])
        elif m == "Log.entryAdded" and p["entry"]["level"] == "error":
            fail("console: %s" % p["entry"].get("text", "")[:300])
        elif m == "Runtime.exceptionThrown":
            fail("exception: %s" % json.dumps(p.get("exceptionDetails"))[:300])
    cdp.call("Target.closeTarget", {"targetId": target})


if __name__ == "__main__":
    try:
        main()
    except Exception as exc:  # a broken page or protocol: a failure, not a crash
        fail("%s: %s" % (type(exc).__name__, exc))
    sys.exit(1 if failures else 0)
