#!/usr/bin/env python3
"""The console's HTTP API without a browser: security (loopback, token, Host and
Origin checks, POST-only actions, path traversal and symbolic links), a dark capture
into session.json, bad requests, the view changed by POST /api/view only, range checks
of every numeric field (400 naming it, nothing changed), the session lock, and the spectrometer's guided
chart (answers, redo, stop and resume).

usage: console_api.py KOGEI PARENT_DIR [TCS.sp] (works in a new directory below it)"""
import http.client
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from console_common import Console, check, fail, failures  # noqa: E402

SIM = "sim:?format=bayer_rggb12&fullwell=20000&read=5&width=320&height=240"


def security(c, work):
    st, body = c.request("GET", "/")
    check(st == 200 and b"kogei console" in body, "GET / serves the page (%d)" % st)
    for asset in ("/console.js", "/console.css"):
        st, _ = c.request("GET", asset)
        check(st == 200, "GET %s: %d" % (asset, st))
    # Path traversal, absolute paths, hidden files: refused, whatever the spelling.
    for path in ("/session/../session.json", "/session/%2e%2e/%2e%2e/etc/passwd",
                 "/session/frames/../../../etc/passwd", "/session//etc/passwd",
                 "/session/.lock", "/out/..%2f..%2fetc%2fpasswd", "/session/%2fetc/passwd",
                 "/session/captures\\..\\..\\x"):
        st, body = c.request("GET", path)
        check(st in (403, 404) and b"root:" not in body,
              "GET %s: expected a refusal, got %d" % (path, st))
    # A symbolic link inside OUTDIR leading out of it is refused; a file inside is served.
    os.makedirs(work + "/S.processed", exist_ok=True)
    with open(work + "/outside.txt", "w") as f:
        f.write("secret outside\n")
    with open(work + "/S.processed/inside.txt", "w") as f:
        f.write("inside\n")
    os.symlink(work + "/outside.txt", work + "/S.processed/leak.txt")
    st, body = c.request("GET", "/out/leak.txt")
    check(st == 403 and b"secret" not in body, "a symlink out of OUTDIR: got %d" % st)
    st, body = c.request("GET", "/out/inside.txt")
    check(st == 200 and body == b"inside\n", "a file in OUTDIR is served (%d)" % st)
    # Actions: POST only, with this page's Origin; the Host must be this console.
    st, _ = c.request("GET", "/api/capture")
    check(st == 405, "GET of an action: expected 405, got %d" % st)
    st, _ = c.request("PUT", "/api/capture", {"kind": "dark"})
    check(st == 405, "PUT: expected 405, got %d" % st)
    st, _ = c.request("POST", "/api/capture", {"kind": "dark"}, origin=False)
    check(st == 403, "POST without Origin: expected 403, got %d" % st)
    st, _ = c.request("POST", "/api/capture", {"kind": "dark"},
                      headers={"Origin": "http://evil.example"})
    check(st == 403, "POST from another origin: expected 403, got %d" % st)
    st, _ = c.request("GET", "/api/state", headers={"Host": "evil.example:80"})
    check(st == 403, "another Host (DNS rebinding): expected 403, got %d" % st)
    check(c.token is None, "no token on 127.0.0.1")


def bad_requests(c):
    for body, word in (({"kind": "bogus"}, "kind"), ({"kind": "dark", "frames": 0}, "frames"),
                       ({"kind": "dark", "name": "../x"}, "name"),
                       ({"kind": "dark", "auto_exposure": True}, "dark"),
                       ({"kind": "dark", "camera": 5}, "camera")):
        st, j = c.json("POST", "/api/capture", body)
        check(st == 400 and word in j.get("error", ""),
              "capture %s: expected 400 naming '%s', got %d %s" % (body, word, st, j))
    st, body = c.request("POST", "/api/capture", None,
                         headers={"Content-Type": "application/json"})
    st, j = c.json("POST", "/api/settings", {"exposure_us": "fast"})
    check(st == 400 and "exposure_us" in j.get("error", ""), "settings: a string exposure (%d)" % st)


def view_and_ranges(c):
    """The live view's settings change by POST /api/view only (with the Origin and Host
    checks); every numeric field is range-checked with a 400 naming it, and a request
    with a bad field changes nothing."""
    for q in ("ev=2", "peaking=1", "x0=0.1&y0=0.1&x1=0.5&y1=0.5", "after=0&ev=-3"):
        st, j = c.json("GET", "/api/live?" + q)
        check(st == 405 and "/api/view" in j.get("error", ""),
              "GET /api/live?%s (a cross-site GET changing the view): expected 405, got %d"
              % (q, st))
    st, _ = c.request("GET", "/api/view")
    check(st == 405, "GET /api/view: expected 405, got %d" % st)
    view = {"ev": 1.5, "peaking": True, "roi": [0.1, 0.2, 0.5, 0.6]}
    st, _ = c.request("POST", "/api/view", {"ev": -3}, headers={"Origin": "http://evil.example"})
    check(st == 403, "POST /api/view from another origin: expected 403, got %d" % st)
    st, _ = c.request("POST", "/api/view", {"ev": -3}, origin=False)
    check(st == 403, "POST /api/view without Origin: expected 403, got %d" % st)
    st, _ = c.request("POST", "/api/view", {"ev": -3}, headers={"Host": "evil.example:80"})
    check(st == 403, "POST /api/view with another Host: expected 403, got %d" % st)
    st, j = c.json("POST", "/api/view", view)
    check(st == 200 and j == view, "POST /api/view: 200 with the view (%d %s)" % (st, j))
    # the next previews are made with it (one under way may have the old one)
    st, j = c.json("GET", "/api/live?after=0")
    for _ in range(3):
        st, j = c.json("GET", "/api/live?after=%d" % j.get("preview", 0))
        if j.get("roi") == view["roi"]:
            break
    check(j.get("roi") == view["roi"], "the preview after POST /api/view uses its focus "
          "region (%s)" % j.get("roi"))
    for body, word in (({"ev": 9}, "ev"), ({"ev": "2"}, "ev"), ({"ev": -8.5}, "ev"),
                       ({"peaking": "yes"}, "peaking"), ({"roi": [0.5, 0.1, 0.2, 0.5]}, "roi"),
                       ({"roi": [0, 0, 1.5, 1]}, "roi"), ({"roi": [0, 0, 1]}, "roi"),
                       ({"ev": -1, "peaking": False, "roi": [-0.1, 0, 1, 1]}, "roi"),
                       ({"ev": -1, "gain": 3}, "gain")):
        st, j = c.json("POST", "/api/view", body)
        check(st == 400 and "'%s'" % word in j.get("error", ""),
              "view %s: expected 400 naming '%s', got %d %s" % (body, word, st, j))
    st, j = c.json("POST", "/api/view", {})
    check(st == 200 and j == view, "bad view requests changed nothing (%s)" % j)
    # camera settings against the camera's range (sim: exposure 10..1e7 us, gain 0..24 dB)
    st, j = c.json("GET", "/api/live?after=0")
    before = j.get("settings", {})
    exp0 = before.get("exposure_us", {}).get("value")
    gain0 = before.get("gain", {}).get("value")
    check(exp0 is not None and gain0 is not None, "the live view reads back exposure and gain")
    new_exp = 2000 if exp0 != 2000 else 3000
    for body, word in (({"gain": 1000}, "gain"), ({"gain": -1}, "gain"),
                       ({"exposure_us": 1}, "exposure_us"), ({"exposure_us": 2e7}, "exposure_us"),
                       ({"exposure_us": new_exp, "gain": 99}, "gain"),
                       ({"exposure_us": new_exp, "iso": "x"}, "iso"),
                       ({"exposure_us": new_exp, "camera": 3}, "camera")):
        st, j = c.json("POST", "/api/settings", body)
        check(st == 400 and "'%s'" % word in j.get("error", ""),
              "settings %s: expected 400 naming '%s', got %d %s" % (body, word, st, j))
    st, j = c.json("GET", "/api/live?after=0")
    st, j = c.json("GET", "/api/live?after=%d" % j.get("preview", 0))
    after = j.get("settings", {})
    check(after.get("exposure_us", {}).get("value") == exp0 and
          after.get("gain", {}).get("value") == gain0,
          "refused settings changed nothing (exposure %s -> %s, gain %s -> %s)"
          % (exp0, after.get("exposure_us", {}).get("value"), gain0,
             after.get("gain", {}).get("value")))
    st, j = c.json("POST", "/api/settings", {"exposure_us": new_exp})
    check(st == 200, "settings in range: 200 (%d %s)" % (st, j.get("error")))
    # captures: every numeric field, nothing started
    _, s0 = c.json("GET", "/api/state")
    for body, word in (({"kind": "object", "target": 1.5}, "target"),
                       ({"kind": "object", "target": 0}, "target"),
                       ({"kind": "object", "auto_exposure": True, "target": "high"}, "target"),
                       ({"kind": "dark", "gain": 1000}, "gain"),
                       ({"kind": "dark", "gain": "high"}, "gain"),
                       ({"kind": "dark", "exposure_us": 1}, "exposure_us"),
                       ({"kind": "dark", "exposure_us": -5}, "exposure_us"),
                       ({"kind": "dark", "frames": "3"}, "frames"),
                       ({"kind": "dark", "frames": 2.5}, "frames"),
                       ({"kind": "dark", "frames": 10001}, "frames"),
                       ({"kind": "dark", "camera": -2}, "camera"),
                       ({"kind": "dark", "auto_exposure": "yes"}, "auto_exposure"),
                       ({"kind": "dark", "meta": "title=x"}, "meta"),
                       ({"kind": "dark", "meta": {"title": 3}}, "meta.title"),
                       ({"kind": "dark", "meta": {"bad key": "x"}}, "meta.bad key"),
                       ({"kind": "dark", "meta": {"notes": "a\nb"}}, "meta.notes"),
                       ({"kind": "dark", "meta": {"notes": "x" * 4097}}, "meta.notes"),
                       ({"kind": "dark", "meta": {"accession": "1987\u202e321"}},
                        "meta.accession"),
                       ({"kind": "dark", "meta": {"title": "a\u200bb"}}, "meta.title"),
                       ({"kind": "dark", "meta": {"notes": "a\u2028b"}}, "meta.notes")):
        st, j = c.json("POST", "/api/capture", body)
        check(st == 400 and "'%s'" % word in j.get("error", ""),
              "capture %s: expected 400 naming '%s', got %d %s" % (body, word, st, j))
    for path, body, word in (("/api/measure", {"resume": "yes"}, "resume"),
                             ("/api/process", {"render": 0}, "render")):
        st, j = c.json("POST", path, body)
        check(st == 400 and "'%s'" % word in j.get("error", ""),
              "%s %s: expected 400 naming '%s', got %d %s" % (path, body, word, st, j))
    # kogei process's access copy and manifest options (one table with the command
    # line's): a bad value names the option, a wrong type or an unknown key the key
    for body, word in (({"access_quality": "0"}, "--access-quality"),
                       ({"iiif_base": "ftp://x"}, "--iiif-base"),
                       ({"access_quality": 90}, "'access_quality'"),
                       ({"iiif_bas": "http://x"}, "'iiif_bas'")):
        st, j = c.json("POST", "/api/process", body)
        check(st == 400 and word in j.get("error", ""),
              "/api/process %s: expected 400 naming %s, got %d %s" % (body, word, st, j))
    for q in ("-1", "x", "1.5"):
        st, j = c.json("GET", "/api/live?after=" + q)
        check(st == 400 and "'after'" in j.get("error", ""),
              "GET /api/live?after=%s: expected 400 naming 'after', got %d" % (q, st))
    _, s1 = c.json("GET", "/api/state")
    check(not s1["job"]["running"] and s1["job"]["title"] == s0["job"]["title"],
          "refused captures started nothing (%s)" % s1["job"]["title"])


def dark_capture(c, work):
    record = {"accession": "1987.12.3", "title": "<i>lid</i> & \u6f06", "rig.id": "A"}
    st, j = c.json("POST", "/api/capture", {"kind": "dark", "frames": 3, "exposure_us": 4000,
                                            "name": "dark-api", "meta": record})
    check(st == 200, "dark capture started (%d %s)" % (st, j))
    s = c.wait_job()
    if not check(s is not None, "the dark capture ended within 60 s"):
        return
    check(not s["job"]["error"], "dark capture: %s" % s["job"]["error"])
    res = s["job"]["result"] or {}
    check(res.get("name") == "dark-api" and res.get("kind") == "dark",
          "the job's summary is the manifest entry (%s)" % res.get("name"))
    stream = res.get("statistics", {}).get("stream", {})
    check(stream.get("completed", 0) >= 3, "stream counts in the summary: %s" % stream)
    with open(work + "/S/session.json") as f:
        man = json.load(f)
    names = [(x["name"], x["kind"]) for x in man["captures"]]
    check(("dark-api", "dark") in names, "session.json lists the dark: %s" % names)
    metas = [x.get("meta") for x in man["captures"] if x["name"] == "dark-api"]
    check(metas == [record], "the capture request's meta in session.json: %s" % metas)
    st, body = c.request("GET", "/session/session.json")
    check(st == 200 and b"dark-api" in body, "the session's manifest is served (%d)" % st)
    st, j = c.json("GET", "/api/session")
    check(any(x["name"] == "dark-api" for x in j["manifest"]["captures"]),
          "/api/session lists the dark")
    # the live view works again after the capture
    st, j = c.json("GET", "/api/live?after=0")
    seq1 = j.get("preview", 0)
    st, j = c.json("GET", "/api/live?after=%d" % seq1)
    check(j.get("preview", 0) > seq1, "the live view runs after a capture (%s)" % j.get("error"))
    st, png = c.request("GET", "/api/live.png")
    check(st == 200 and png[:8] == b"\x89PNG\r\n\x1a\n", "live.png is a PNG (%d)" % st)
    # the page's live view: the next preview itself, its numbers in headers
    st, j = c.json("GET", "/api/live")
    seq = j.get("preview", 0)
    conn = http.client.HTTPConnection(c.host, c.port, timeout=30)
    conn.request("GET", "/api/preview?after=%d" % seq, headers={"Host": c.hostport})
    r = conn.getresponse()
    img = r.read()
    n = int(r.getheader("X-Kogei-Preview") or 0)
    live = json.loads(r.getheader("X-Kogei-Live") or "{}")
    check(r.status == 200 and n > seq and live.get("preview") == n,
          "GET /api/preview?after=%d: %d, preview %d, its numbers %s" % (seq, r.status, n,
                                                                         live.get("preview")))
    jpeg = r.getheader("Content-Type") == "image/jpeg"
    check(img[:2] == b"\xff\xd8" if jpeg else img[:8] == b"\x89PNG\r\n\x1a\n",
          "the preview is the image its Content-Type says (%s)" % r.getheader("Content-Type"))
    cap = float(r.getheader("X-Kogei-Captured-Ms") or 0)
    check(abs(cap - time.time() * 1000) < 60000, "X-Kogei-Captured-Ms is the wall clock: %s" % cap)
    conn.close()
    for q in ("-1", "1.5", "x"):
        st, _ = c.request("GET", "/api/preview?after=" + q)
        check(st == 400, "GET /api/preview?after=%s: expected 400, got %d" % (q, st))
    st, _ = c.request("GET", "/api/preview?after=0", headers={"Host": "evil.example:80"})
    check(st == 403, "GET /api/preview with another Host: expected 403, got %d" % st)


def second_console(kogei, work):
    r = subprocess.run([kogei, "console", "--session", work + "/S", "--listen", "127.0.0.1:0"],
                       capture_output=True, text=True, timeout=20)
    check(r.returncode == 1 and "lock" in r.stderr,
          "a second console on the session is refused (exit %d: %s)" % (r.returncode,
                                                                         r.stderr.strip()))


def token(kogei, work):
    c = Console(kogei, work + "/T", [SIM], listen="127.0.0.2:0")
    try:
        check(c.token is not None and len(c.token) == 32, "a token is printed for 127.0.0.2")
        for path in ("/", "/api/state", "/api/live.png", "/api/preview?after=0",
                     "/session/session.json"):
            st, body = c.request("GET", path, token=False)
            check(st == 403 and b"token" in body, "GET %s without the token: %d" % (path, st))
        st, _ = c.request("GET", "/api/state", token=False,
                          headers={"X-Kogei-Token": "0" * 32})
        check(st == 403, "a wrong token: %d" % st)
        st, _ = c.request("GET", "/api/state?token=" + c.token, token=False)
        check(st == 200, "the token as ?token=: %d" % st)
        st, _ = c.request("GET", "/api/state")
        check(st == 200, "the token as X-Kogei-Token: %d" % st)
        st, _ = c.request("POST", "/api/capture", {"kind": "dark", "frames": 1}, token=False)
        check(st == 403, "an action without the token: %d" % st)
    finally:
        c.stop()


def measure(kogei, work, tcs):
    out = work + "/M.chart.cgats"
    c = Console(kogei, work + "/M", [SIM], extra=["--spectro", "sim:" + tcs, "--layout",
                                                   "cie-tcs-frame", "--spectra-out", out])
    try:
        def answer(a, expect=200):
            st, j = c.json("POST", "/api/measure/answer", {"answer": a})
            check(st == expect, "answer %s: %d %s" % (a, st, j.get("error")))

        def wait_prompt():
            deadline = time.time() + 30
            while time.time() < deadline:
                _, s = c.json("GET", "/api/state")
                if s["job"]["waiting"] or not s["job"]["running"]:
                    return s
                time.sleep(0.05)
            return s

        st, j = c.json("POST", "/api/measure", {})
        check(st == 200, "measurement started (%d %s)" % (st, j))
        s = wait_prompt()
        check("Cover the probe" in (s["job"]["prompt"] or ""), "first prompt: the dark")
        answer("r", 400)  # no redo before a patch
        answer("m")       # dark
        wait_prompt()
        answer("m")       # white
        for _ in range(3):
            s = wait_prompt()
            answer("m")
        s = wait_prompt()
        check("r" in s["job"]["allowed"], "redo offered after a patch")
        answer("r")
        s = wait_prompt()
        check(any("again" in line for line in s["job"]["log"]), "redo asks for the patch again")
        answer("q")
        s = c.wait_job(30)
        check(s["spectra_partial"] and not s["spectra_measured"],
              "stopped: the .partial file holds what was measured")
        st, j = c.json("POST", "/api/measure", {"resume": True})
        check(st == 200, "resumed (%d)" % st)
        n = 0
        while n < 40:
            s = wait_prompt()
            if not s["job"]["running"]:
                break
            answer("m")
            n += 1
        check(not s["job"]["error"], "measurement: %s" % s["job"]["error"])
        check(os.path.exists(out) and not os.path.exists(out + ".partial"),
              "the chart's spectra are written and the .partial file removed")
        with open(out) as f:
            text = f.read()
        ids = [l.split()[0] for l in text.split("BEGIN_DATA\n")[1].splitlines()
               if l and not l.startswith("END_DATA")]
        check(len(ids) == (s["job"]["result"] or {}).get("patches", -1),
              "every patch measured once (%d rows)" % len(ids))
        check(any("resuming: 3 of" in line for line in s["job"]["log"]),
              "the resumed run starts from the 3 saved patches")
    finally:
        c.stop()


def main():
    kogei, parent = sys.argv[1:3]
    work = tempfile.mkdtemp(prefix="console-api-", dir=parent)
    tcs = sys.argv[3] if len(sys.argv) > 3 else "/usr/share/colord/ref/CIE-TCS.sp"
    c = Console(kogei, work + "/S", [SIM])
    try:
        security(c, work)
        bad_requests(c)
        view_and_ranges(c)
        dark_capture(c, work)
        second_console(kogei, work)
    finally:
        rc = c.stop()
        check(rc == 0, "the console stops on SIGTERM with 0 (got %s)" % rc)
    token(kogei, work)
    if os.path.exists(tcs):
        measure(kogei, work, tcs)
    else:
        print("note: %s missing (colord-data): the spectrometer part is skipped" % tcs)
    print("console-api: %s" % ("FAIL (%d)" % len(failures) if failures else "ok"))
    if not failures:
        shutil.rmtree(work)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
