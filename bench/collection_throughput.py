#!/usr/bin/env python3
"""A collection's throughput: the README's first session at 12 Mpix, one `kogei process`
of it timed stage by stage, then a collection of copies of it through `kogei collection
run` with the local engine at 1 and 2 jobs and through a private single-node Slurm.

The session is the README's (a sim camera looking at the CIE test-colour chart in its
AprilTag frame and at tiles of the library's metals, `kogei acquire` of a dark, a flat,
the chart and one object, `kogei measure` of the chart), made with 4000 x 3000 images
instead of 800 x 600 (the object's tiles five times larger). It is made once in the
work folder and kept.

Stages: one `kogei process S --spectra chart.cgats -o OUT` with its progress lines
(standard error) timestamped; each line is put in a stage by its words (session,
chart, calibrate, estimate, master, labels, scene export, render, report), a stage
runs from its first line to the next stage's, and the process's CPU time (user +
system, all threads, from /proc/PID/stat, read as each line arrives) is split the
same way: on a machine shared with other work the wall time of a stage grows with the
load, its CPU time much less. Peak resident memory, user and system time come from
wait4.

Throughput: --sessions hard-linked copies of the session in one list; `kogei
collection run LIST -o OUT` with --engine local --jobs 1, --jobs 2, and --engine slurm
--jobs 2 inside scripts/with-slurm.sh (needs root and the Slurm packages; the row says
why when it cannot run). Objects per hour = objects done / wall time of the collection
command x 3600 (for Slurm: from sbatch to the record written, the cluster's start and
stop not counted). The peak resident memory is the largest process of the run's (a
worker's `kogei process`). Each run's OUT is removed after it (a 12 Mpix f32 cube is
2.9 GB).

    bench/collection_throughput.py [--kogei build/cli/kogei] [--work DIR]
        [--sessions N] [--no-stages] [--no-collection] [--no-slurm] [-o REPORT.md]

It is a program, never a test: nothing here asserts a speed."""
import argparse
import datetime
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.dirname(HERE)
TCS = "/usr/share/colord/ref/CIE-TCS.sp"
CLK = os.sysconf("SC_CLK_TCK")


def cpu_name():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def log(msg):
    print("collection_throughput: " + msg, file=sys.stderr, flush=True)


def run_checked(argv, cwd=None):
    p = subprocess.run(argv, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if p.returncode != 0:
        sys.exit("collection_throughput: %s exited %d:\n%s" % (" ".join(argv), p.returncode,
                                                                 p.stdout[-3000:]))


def make_session(kogei, work):
    """The README's first session at 4000 x 3000 in work/session (S, chart.cgats)."""
    d = os.path.join(work, "session")
    s, cgats = os.path.join(d, "S"), os.path.join(d, "chart.cgats")
    if os.path.exists(os.path.join(s, "session.json")) and os.path.exists(cgats):
        return s, cgats
    if not os.path.exists(TCS):
        sys.exit("collection_throughput: %s missing (package colord-data)" % TCS)
    if os.path.exists(d):
        shutil.rmtree(d)
    os.makedirs(d)
    log("making the README's session at 12 Mpix in %s (about 2 minutes)" % d)
    cam = "format=bayer_rggb12&fullwell=20000&read=5&serial=site-1"
    steps = [
        [kogei, "sim", "chart", "--layout", "cie-tcs-frame", "--spectra", TCS, "--camera",
         "demo-site", "--illuminant", "A", "--tilt", "25", "--width", "4000", "--height", "3000",
         "-o", "chart.tif"],
        [kogei, "sim", "image", "--materials", "default", "--camera", "demo-site", "--illuminant",
         "A", "--angle", "30", "--patch-size", "200", "--size", "4000x3000", "-o", "object.tif"],
        [kogei, "acquire", "--camera", "sim:chart.tif?%s&light=0" % cam, "--out", "S", "--kind",
         "dark", "--exposure", "10000", "--gain", "0"],
        [kogei, "acquire", "--camera", "sim:chart.tif?%s&uniform=0.6" % cam, "--out", "S",
         "--kind", "flat", "--exposure", "10000", "--gain", "0"],
        [kogei, "acquire", "--camera", "sim:chart.tif?%s" % cam, "--out", "S", "--kind", "chart",
         "--exposure", "10000", "--gain", "0", "--layout", "cie-tcs-frame"],
        [kogei, "acquire", "--camera", "sim:object.tif?%s" % cam, "--out", "S", "--kind",
         "object", "--exposure", "10000", "--gain", "0", "--meta", "accession=2026.1.1",
         "--meta", "title=Alloy coupons", "--meta", "operator=me"],
        [kogei, "measure", "--spectro", "sim:" + TCS, "--chart", "cie-tcs-frame", "--yes", "-o",
         "chart.cgats"],
    ]
    for argv in steps:
        run_checked(argv, cwd=d)
    for f in ("chart.tif", "object.tif"):
        os.unlink(os.path.join(d, f))
    return s, cgats


# The stage of a progress line of `kogei process` (first match wins).
STAGES = [
    ("report", re.compile(r": done$|wrote .*process\.json|report")),
    ("render", re.compile(r"render")),
    ("scene export", re.compile(r"writing object\.glb|writing .*mitsuba|scene")),
    ("labels", re.compile(r"classif|labels")),
    ("master", re.compile(r"master")),
    ("estimate", re.compile(r"estimat|cube")),
    ("calibrate", re.compile(r"reference|calibration|profile|chart found|M2")),
    ("chart (read + detect)", re.compile(r"chart")),
    ("session (read)", re.compile(r"session")),
]


def stage_of(line):
    for name, rx in STAGES:
        if rx.search(line):
            return name
    return None


def proc_cpu(pid):
    """User + system seconds of a running process (all its threads); None when gone."""
    try:
        with open("/proc/%d/stat" % pid) as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / CLK
    except (OSError, IndexError, ValueError):
        return None


def stages(kogei, session, cgats, out):
    if os.path.exists(out):
        shutil.rmtree(out)
    argv = [kogei, "process", session, "--spectra", cgats, "-o", out]
    t0 = time.monotonic()
    p = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    marks = []  # (wall, cpu, line)
    last_cpu = 0.0
    for line in p.stderr:
        c = proc_cpu(p.pid)
        last_cpu = c if c is not None else last_cpu
        marks.append((time.monotonic() - t0, last_cpu, line.rstrip("\n")))
    _, status, ru = os.wait4(p.pid, 0)
    end = time.monotonic() - t0
    total_cpu = ru.ru_utime + ru.ru_stime
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit("collection_throughput: %s failed:\n%s" % (" ".join(argv),
                                                            "\n".join(m[2] for m in marks[-5:])))
    # per stage: from the first line of a stage to the first line of the next
    rows, steps = [], []
    cur, cur_w, cur_c = "session (read)", 0.0, 0.0
    prev_w, prev_c, prev_line = 0.0, 0.0, "(start)"
    for w, c, line in marks:
        steps.append((w - prev_w, c - prev_c, prev_line))
        prev_w, prev_c, prev_line = w, c, line
        st = stage_of(line) or cur
        if st != cur:
            rows.append([cur, w - cur_w, c - cur_c])
            cur, cur_w, cur_c = st, w, c
    steps.append((end - prev_w, total_cpu - prev_c, prev_line))
    rows.append([cur, end - cur_w, total_cpu - cur_c])
    merged = {}
    order = []
    for name, w, c in rows:
        if name not in merged:
            merged[name] = [0.0, 0.0]
            order.append(name)
        merged[name][0] += w
        merged[name][1] += c
    shutil.rmtree(out, ignore_errors=True)
    return {
        "argv": argv,
        "wall": end,
        "user": ru.ru_utime,
        "sys": ru.ru_stime,
        "maxrss_mib": ru.ru_maxrss / 1024.0,
        "stages": [(n, merged[n][0], merged[n][1]) for n in order],
        "steps": steps,
    }


def collection_run(kogei, listfile, out, engine, jobs, slurm_wrapper=None):
    """One `kogei collection run`; a dict with wall, exit, maxrss, counts, or why not."""
    if os.path.exists(out):
        shutil.rmtree(out)
    argv = [kogei, "collection", "run", listfile, "-o", out, "--engine", engine, "--jobs",
            str(jobs)]
    logf = out + ".log"
    if slurm_wrapper:
        timef = out + ".time"
        inner = [sys.executable, "-c",
                 "import os,sys,time,subprocess\n"
                 "t=time.monotonic(); p=subprocess.Popen(sys.argv[2:])\n"
                 "_,s,ru=os.wait4(p.pid,0)\n"
                 "open(sys.argv[1],'w').write('%f %d %d' % (time.monotonic()-t, "
                 "os.waitstatus_to_exitcode(s), ru.ru_maxrss))\n"
                 "sys.exit(os.waitstatus_to_exitcode(s))", timef] + argv
        with open(logf, "w") as lf:
            rc = subprocess.call([slurm_wrapper] + inner, stdout=lf, stderr=subprocess.STDOUT)
        if rc == 77 or not os.path.exists(timef):
            with open(logf) as lf:
                why = lf.read().strip().splitlines()
            return {"skipped": (why[-1] if why else "with-slurm.sh exited %d" % rc)}
        with open(timef) as f:
            wall, code, rss = f.read().split()
        # slurmd runs the tasks, not this process: their memory is not in wait4's
        res = {"wall": float(wall), "exit": int(code), "maxrss_mib": None}
    else:
        t0 = time.monotonic()
        with open(logf, "w") as lf:
            p = subprocess.Popen(argv, stdout=lf, stderr=subprocess.STDOUT)
            _, status, ru = os.wait4(p.pid, 0)
        res = {"wall": time.monotonic() - t0, "exit": os.waitstatus_to_exitcode(status),
               "maxrss_mib": ru.ru_maxrss / 1024.0, "cpu": ru.ru_utime + ru.ru_stime}
    try:
        with open(os.path.join(out, "collection.json")) as f:
            rec = json.load(f)
        entries = rec.get("entries", [])
        res["done"] = sum(1 for e in entries if e.get("status") == "done")
        res["objects"] = sum(len(e.get("objects", [])) for e in entries
                             if e.get("status") == "done")
        secs = [e.get("time", {}).get("seconds") for e in entries]
        res["entry_seconds"] = [s for s in secs if isinstance(s, (int, float))]
    except (OSError, ValueError) as e:
        res["done"], res["objects"], res["entry_seconds"] = 0, 0, []
        res["error"] = "no collection.json: %s" % e
    with open(logf) as lf:
        res["log_tail"] = lf.read()[-600:]
    shutil.rmtree(out, ignore_errors=True)
    return res


def report(args, load0, load1, st, runs, started):
    o = []
    o.append("# A collection's throughput\n")
    o.append("Run: %s UTC on %s, %d online CPUs; load average %s before, %s after; "
             "`bench/collection_throughput.py%s`.\n" % (
                 started, cpu_name(), os.cpu_count(), load0, load1,
                 " --sessions %d" % args.sessions))
    o.append("The session: the README's first session with 4000 x 3000 (12 Mpix) captures (a "
             "dark, a flat, the CIE test-colour chart in its frame, one object of metal "
             "tiles), processed with `kogei process S --spectra chart.cgats -o OUT` "
             "(defaults: f32 cube of 61 bands, 2.9 GB).\n")
    if st:
        o.append("## One `kogei process`, stage by stage\n")
        o.append("Wall %.1f s, CPU %.1f s user + %.1f s system, peak RSS %.0f MiB. A stage "
                 "runs from its first progress line to the next stage's; CPU is the "
                 "process's (all threads) over the same span.\n" % (
                     st["wall"], st["user"], st["sys"], st["maxrss_mib"]))
        o.append("| stage | wall (s) | share | CPU (s) |")
        o.append("|---|--:|--:|--:|")
        for name, w, c in st["stages"]:
            o.append("| %s | %.2f | %.0f %% | %.2f |" % (name, w, 100 * w / st["wall"], c))
        slow = max(st["stages"], key=lambda r: r[1])
        slow_cpu = max(st["stages"], key=lambda r: r[2])
        o.append("\nSlowest stage by wall time: %s (%.1f s); by CPU time: %s (%.1f s).\n" % (
            slow[0], slow[1], slow_cpu[0], slow_cpu[2]))
        o.append("<details><summary>Every progress line</summary>\n")
        o.append("| wall (s) | CPU (s) | from the line |")
        o.append("|--:|--:|---|")
        for w, c, line in st["steps"]:
            o.append("| %.2f | %.2f | %s |" % (w, c, line.replace("|", "/")[:110]))
        o.append("\n</details>\n")
    if runs:
        o.append("## Objects per hour\n")
        o.append("%d copies of the session (hard links), one object each, in one list; "
                 "`kogei collection run LIST -o OUT --engine E --jobs N`. Wall: the "
                 "collection command (Slurm: from sbatch to the record written; the "
                 "cluster's start and stop not counted). CPU per object: user + system "
                 "time of the whole run (wait4: every worker and `kogei process`) over the "
                 "objects; on a machine shared with other work the wall time grows with "
                 "the load, the CPU time much less.\n" % args.sessions)
        o.append("| engine | jobs | sessions done | objects | wall (s) | objects per hour | "
                 "per session (s, median of the record's times) | CPU per object (s) | "
                 "peak RSS of a worker (MiB) |")
        o.append("|---|--:|--:|--:|--:|--:|--:|--:|--:|")
        for name, jobs, r in runs:
            if "skipped" in r:
                o.append("| %s | %d | - | - | - | not run: %s | - | - | - |" % (
                    name, jobs, r["skipped"][:120]))
                continue
            secs = sorted(r["entry_seconds"])
            med = secs[len(secs) // 2] if secs else float("nan")
            oph = r["objects"] / r["wall"] * 3600 if r["wall"] > 0 else float("nan")
            cpu = r.get("cpu")
            o.append("| %s | %d | %d | %d | %.1f | %.0f | %.1f | %s | %s |" % (
                name, jobs, r["done"], r["objects"], r["wall"], oph, med,
                "%.1f" % (cpu / r["objects"]) if cpu and r["objects"] else "(slurmd's tasks)",
                "%.0f" % r["maxrss_mib"] if r["maxrss_mib"] else "(slurmd's tasks)"))
        o.append("")
    return "\n".join(o) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kogei", default=os.path.join(SOURCE, "build", "cli", "kogei"))
    ap.add_argument("--work", default=None, help="scratch folder (default: a new one in /tmp)")
    ap.add_argument("--sessions", type=int, default=4)
    ap.add_argument("--no-stages", action="store_true")
    ap.add_argument("--no-collection", action="store_true")
    ap.add_argument("--no-slurm", action="store_true")
    ap.add_argument("-o", dest="output")
    args = ap.parse_args()
    if args.sessions < 1:
        sys.exit("collection_throughput: --sessions must be at least 1")
    kogei = os.path.abspath(args.kogei)
    if not os.access(kogei, os.X_OK):
        sys.exit("collection_throughput: %s: not an executable (build first, or --kogei)" % kogei)
    started = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M")
    load0 = "%.2f" % os.getloadavg()[0]
    work = args.work or tempfile.mkdtemp(prefix="kogei-collection-bench-")
    os.makedirs(work, exist_ok=True)
    session, cgats = make_session(kogei, work)
    st = None
    if not args.no_stages:
        log("one kogei process, stage by stage")
        st = stages(kogei, session, cgats, os.path.join(work, "process-out"))
    runs = []
    if not args.no_collection:
        has = subprocess.run([kogei, "collection", "run", "--help"], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL).returncode == 0
        if not has:
            runs.append(("local", 1, {"skipped": "this kogei has no `kogei collection`"}))
        else:
            coll = os.path.join(work, "collection")
            if os.path.exists(coll):
                shutil.rmtree(coll)
            os.makedirs(coll)
            rows = ["session,spectra,name"]
            for i in range(args.sessions):
                d = os.path.join(coll, "s%02d" % i)
                subprocess.check_call(["cp", "-al", session, d])
                rows.append("s%02d,%s,obj%02d" % (i, cgats, i))
            listfile = os.path.join(coll, "list.csv")
            with open(listfile, "w") as f:
                f.write("\n".join(rows) + "\n")
            for jobs in (1, 2):
                log("kogei collection run --engine local --jobs %d (%d sessions)" % (
                    jobs, args.sessions))
                runs.append(("local", jobs, collection_run(
                    kogei, listfile, os.path.join(work, "out-local-%d" % jobs), "local", jobs)))
            if not args.no_slurm:
                log("kogei collection run --engine slurm --jobs 2 in a private single-node Slurm")
                runs.append(("slurm (single node, 2 CPUs)", 2, collection_run(
                    kogei, listfile, os.path.join(work, "out-slurm"), "slurm", 2,
                    slurm_wrapper=os.path.join(SOURCE, "scripts", "with-slurm.sh"))))
            shutil.rmtree(coll, ignore_errors=True)
    load1 = "%.2f" % os.getloadavg()[0]
    text = report(args, load0, load1, st, runs, started)
    for name, jobs, r in runs:
        if r.get("exit") not in (None, 0):
            log("%s --jobs %d exited %s; log tail:\n%s" % (name, jobs, r.get("exit"),
                                                          r.get("log_tail", "")))
    sys.stdout.write(text)
    if args.output:
        tmp = args.output + ".tmp"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, args.output)


if __name__ == "__main__":
    main()
