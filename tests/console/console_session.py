#!/usr/bin/env python3
"""A whole sim session through the console's API alone, as the page drives it: the
scenes of tests/pipeline/sim_session.sh, a dark, a flat, the chart check (GO), the
chart, an object, the spectrometer's chart, kogei process, the report served, and the
deposit of the results with their session into a BagIt bag.

usage: console_session.py KOGEI SOURCE_ROOT PARENT_DIR"""
import os
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from console_common import Console, check, failures  # noqa: E402

TCS = "/usr/share/colord/ref/CIE-TCS.sp"
CAM = "format=bayer_rggb12&fullwell=20000&read=5&serial=site-1"


def scenes(kogei, fix, work):
    common = ["--camera", fix + "/demo/site_camera.csv", "--illuminant", "A",
              "--white-level", "0.9", "--noise", "none", "--depth", "float"]
    subprocess.run([kogei, "sim", "chart", "--layout", "cie-tcs-frame", "--spectra", TCS,
                    "--tilt", "25", "--tilt-axis", "120", "--rotate", "5", "--blur", "1",
                    "--vignetting", "0.1", "--seed", "2", "--width", "800", "--height", "600",
                    "--fov", "40", "--fill", "0.85", "--paper", "0.85", "--ink", "0.03",
                    "--background", "0.2", "-o", work + "/chart.tif"] + common,
                   check=True, stdout=subprocess.DEVNULL)
    subprocess.run([kogei, "sim", "image", "--materials", "default", "--angle", "30",
                    "--patch-size", "40", "--gap", "10", "--columns", "5", "--background", "0",
                    "--size", "800x600", "-o", work + "/object.tif"] + common,
                   check=True, stdout=subprocess.DEVNULL)


def capture(c, body):
    st, j = c.json("POST", "/api/capture", body)
    check(st == 200, "capture %s started: %d %s" % (body, st, j.get("error")))
    s = c.wait_job(90)
    check(s and not s["job"]["error"], "capture %s: %s" % (body, s and s["job"]["error"]))
    return s


def deposit(c, kogei, work):
    """POST /api/deposit: OUTDIR into OUTDIR.bag through kogei deposit's options as JSON;
    requests with a key the page may not set or a value of the wrong kind refused."""
    bag = work + "/S.processed.bag"
    for body, key in (({"bag": "/tmp/elsewhere"}, "'bag'"), ({"with_session": "yes"},
                      "'with_session'"), ({"contact_name": "A\nB"}, "--contact-name"),
                      ({"config": "/etc/passwd"}, "'config'")):
        st, j = c.json("POST", "/api/deposit", body)
        check(st == 400 and key in (j.get("error") or ""),
              "deposit %s refused naming %s: %d %s" % (body, key, st, j.get("error")))
    check(not os.path.exists(bag), "nothing deposited by the refused requests")
    st, j = c.json("POST", "/api/deposit", {"with_session": True,
                                            "source_organization": "Kogei Test Museum",
                                            "contact_email": "lab@example.org"})
    check(st == 200, "deposit started: %d %s" % (st, j.get("error")))
    s = c.wait_job(120)
    check(s and not s["job"]["error"], "deposit: %s" % (s and s["job"]["error"]))
    res = (s and s["job"]["result"]) or {}
    check(res.get("bag") == bag and res.get("files", 0) > 10,
          "deposit: the bag beside OUTDIR: %s" % res)
    info = open(bag + "/bag-info.txt").read() if os.path.exists(bag + "/bag-info.txt") else ""
    check("Source-Organization: Kogei Test Museum\n" in info and
          "Contact-Email: lab@example.org\n" in info, "deposit: bag-info.txt %r" % info)
    check(os.path.exists(bag + "/data/session/session.json") and
          os.path.exists(bag + "/data/results/process.json"),
          "deposit with_session: data/results/ and data/session/")
    r = subprocess.run([kogei, "deposit", "--verify", bag], capture_output=True, text=True)
    check(r.returncode == 0 and ": valid: %d files" % res.get("files", -1) in r.stdout,
          "the console's bag verifies: %s %s" % (r.stdout, r.stderr))


def main():
    kogei, root, parent = sys.argv[1:4]
    if not os.path.exists(TCS):
        print("SKIP: %s missing (colord-data)" % TCS)
        return 77
    work = tempfile.mkdtemp(prefix="console-session-", dir=parent)
    scenes(kogei, root + "/fixtures", work)
    chart, obj = work + "/chart.tif", work + "/object.tif"
    cams = ["sim:%s?%s&light=0" % (chart, CAM), "sim:%s?%s&uniform=0.6" % (chart, CAM),
            "sim:%s?%s" % (chart, CAM), "sim:%s?%s" % (obj, CAM)]
    c = Console(kogei, work + "/S", cams, extra=["--layout", "cie-tcs-frame", "--spectro",
                                                 "sim:" + TCS, "--frames", "4"])
    try:
        capture(c, {"kind": "dark", "camera": 0, "exposure_us": 10000, "gain": 0})
        capture(c, {"kind": "flat", "camera": 1, "exposure_us": 10000, "gain": 0})
        st, j = c.json("POST", "/api/settings", {"camera": 2, "exposure_us": 10000, "gain": 0})
        check(st == 200, "settings: %d %s" % (st, j.get("error")))
        st, j = c.json("GET", "/api/chart")
        check(j.get("found") and j.get("go"), "chart check GO: %s %s" % (j.get("error"),
                                                                         j.get("reasons")))
        check(j.get("detector") == "apriltag" and not j.get("tagless"),
              "the framed chart found by its tags: %s" % j.get("detector"))
        s = capture(c, {"kind": "chart", "camera": 2, "exposure_us": 10000, "gain": 0})
        check(s["job"]["result"].get("chart_layout") == "cie-tcs-frame",
              "the chart capture records its layout")
        capture(c, {"kind": "object", "camera": 3, "exposure_us": 10000, "gain": 0})
        st, _ = c.json("POST", "/api/measure", {})
        check(st == 200, "spectrometer chart started")
        deadline = time.time() + 60
        while time.time() < deadline:
            _, s = c.json("GET", "/api/state")
            if not s["job"]["running"]:
                break
            if s["job"]["waiting"]:
                c.json("POST", "/api/measure/answer", {"answer": "m"})
            else:
                time.sleep(0.05)
        check(s["spectra_measured"] and not s["job"]["error"],
              "spectrometer chart measured: %s" % s["job"]["error"])
        st, j = c.json("POST", "/api/process", {"render": False})
        check(st == 200, "process started: %d %s" % (st, j.get("error")))
        s = c.wait_job(150)
        check(s and not s["job"]["error"], "process: %s" % (s and s["job"]["error"]))
        check(s and any("report.html" in line for line in s["job"]["log"]),
              "process's progress lines reach the page")
        check(s and s["report"] and s["job"]["result"]["objects"] == 1,
              "process: one object, the report written")
        st, body = c.request("GET", "/out/report.html")
        check(st == 200 and b"<section" in body, "the report is served (%d)" % st)
        # A second job of the same console: the object again (render is part of its
        # key), its earlier folder replaced although the first job read files in it.
        st, j = c.json("POST", "/api/process", {"render": True})
        check(st == 200, "process again started: %d %s" % (st, j.get("error")))
        s = c.wait_job(150)
        check(s and not s["job"]["error"], "process again: %s" % (s and s["job"]["error"]))
        check(s and s["job"]["result"] and s["job"]["result"]["processed"] == 1,
              "process again: the object processed anew")
        deposit(c, kogei, work)
        _, m = c.json("GET", "/api/session")
        kinds = sorted(x["kind"] for x in m["manifest"]["captures"])
        check(kinds == ["chart", "dark", "flat", "object"], "the session holds %s" % kinds)
    finally:
        c.stop()
    print("console-session: %s" % ("FAIL (%d)" % len(failures) if failures else "ok"))
    if not failures:
        shutil.rmtree(work)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
