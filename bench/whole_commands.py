#!/usr/bin/env python3
"""Whole commands, timed and profiled: `kogei estimate` of a 12 Mpix 16-bit TIFF to an
ENVI f32 cube, and `kogei process` of the demo's site session (chart, calibration,
an 800x600 object: cube, camera-space labels, scene, render, report).

Each command runs once with the page cache dropped (cold: its inputs come from disk;
needs root, otherwise the cold row says it was not dropped), then --reps times warm;
wall time is the median of the warm runs, user and system CPU and peak resident memory
come from wait4. Then one more warm run under `perf record -e cpu-clock -g` (a software
clock: no hardware counters are needed) gives where the time goes, by function
(self time, the top entries) and by the stage the function belongs to.

    bench/whole_commands.py [--kogei build/cli/kogei] [--work DIR] [--reps N]
                            [--no-perf] [-o REPORT.md]

The report (Markdown) goes to standard output and, with -o, to a file. It is a
program, never a test: nothing here asserts a speed."""
import argparse
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.dirname(HERE)


def cpu_name():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def drop_caches():
    """Drop the page cache; False when this process may not."""
    try:
        os.sync()
        with open("/proc/sys/vm/drop_caches", "w") as f:
            f.write("3\n")
        return True
    except OSError:
        return False


def run(argv, quiet=True):
    """Run argv; (wall s, user s, sys s, peak RSS MiB)."""
    t0 = time.monotonic()
    out = subprocess.DEVNULL if quiet else None
    p = subprocess.Popen(argv, stdout=out, stderr=out)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.monotonic() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit("whole_commands: %s failed (exit %d)" %
                 (" ".join(argv), os.waitstatus_to_exitcode(status)))
    return wall, ru.ru_utime, ru.ru_stime, ru.ru_maxrss / 1024.0


# Which stage a function's self time belongs to: by its library, then by its name
# (first match wins).
DSO_STAGES = [
    ("libembree", "Embree (BVH, traversal)"),
    ("libapriltag", "chart: tags (libapriltag)"),
    ("libopencv", "OpenCV (demosaicing, mcc)"),
    ("libtiff", "image reading and writing (libtiff)"),
    ("libpng", "PNG writing (libpng)"),
    ("libz.", "zlib (PNG and TIFF compression)"),
    ("libm.", "libm (exp, pow, atan2, sincos)"),
    ("libjansson", "JSON (jansson)"),
    ("[kernel", "kernel: page cache, faults, copies"),
]
SYMBOL_STAGES = [
    ("render: shading, sampling", ("render", "shade", "shading", "bsdf", "fresnel", "trace",
                                   "camera_ray", "hero", "rd_sample", "rd_eval", "rd_material",
                                   "kg_beckmann", "kg_lobe")),
    ("camera-space matching", ("kg_cs_", "cs_match", "match16", "match8", "cam_compute",
                               "quad32", "fit_subset", "composition_pixel")),
    ("labels: survey, regions, outputs", ("labels", "region", "survey", "classif", "geometry_of")),
    ("estimation kernels", ("bsq", "est_", "matrix_", "kg_est")),
    ("chart: sampling, fitting", ("chart", "sample", "grey8", "robust", "select", "radix",
                                  "white_level", "prepare_image", "homograph",
                                  "refine_lm")),
    ("demosaicing, dark, flat", ("demosaic", "bilinear", "capture_rows", "correct")),
    ("image rows", ("kg_image", "rows_read", "unpack")),
    ("previews and report", ("preview", "report", "png", "base64", "overlay")),
    ("memory (libc memcpy, memset)", ("memcpy", "memset", "memmove")),
    ("C library I/O", ("fputc", "fwrite", "fprintf", "vfprintf", "pwrite", "write")),
]


def stage_of(dso, symbol):
    for key, name in DSO_STAGES:
        if dso.startswith(key):
            return name
    for name, keys in SYMBOL_STAGES:
        for k in keys:
            if k in symbol:
                return name
    return "other (%s)" % dso


PERF_LINE = re.compile(r"^\s*([0-9.]+)%\s+(\S+)\s+\[(.)\]\s+(.*?)\s*$")


def perf_profile(argv, data):
    """Self time by function and by stage from one perf run:
    ([(pct, dso, symbol)], {stage: pct}), or None without perf."""
    if shutil.which("perf") is None:
        return None
    r = subprocess.run(["perf", "record", "-q", "-e", "cpu-clock", "-F", "1999", "-g",
                        "-o", data, "--"] + argv,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    if r.returncode != 0:
        return None
    rep = subprocess.run(["perf", "report", "-i", data, "--stdio", "--no-children",
                          "--sort", "dso,sym", "-g", "none", "--percent-limit", "0.05"],
                         capture_output=True, text=True)
    rows = []
    for line in rep.stdout.splitlines():
        m = PERF_LINE.match(line)
        if not m:
            continue
        sym = re.sub(r"\s+-\s+-$", "", m.group(4)).strip()
        rows.append((float(m.group(1)), m.group(2), sym))
    stages = {}
    for pct, dso, sym in rows:
        st = stage_of(dso, sym)
        stages[st] = stages.get(st, 0.0) + pct
    return rows, stages


def timeline(argv):
    """One run with its progress lines (standard error) timestamped: [(seconds the line's
    stage took until the next line, line)], the last line's up to the exit."""
    t0 = time.monotonic()
    p = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    lines = []
    for line in p.stderr:
        lines.append((time.monotonic() - t0, line.rstrip("\n")))
    p.wait()
    end = time.monotonic() - t0
    out = []
    prev_t, prev_line = 0.0, "(start to the first line)"
    for t, line in lines:
        out.append((t - prev_t, prev_line))
        prev_t, prev_line = t, line
    out.append((end - prev_t, prev_line))
    return out, end


def measure(name, argv_of, reps, perf, work, fresh):
    """Cold run, warm runs, a perf run; argv_of(i) gives the i-th run's command."""
    rec = {"name": name}
    if fresh:
        fresh()
    dropped = drop_caches()
    rec["cold"] = run(argv_of(0))
    rec["dropped"] = dropped
    warm = []
    for i in range(reps):
        if fresh:
            fresh()
        warm.append(run(argv_of(i + 1)))
    rec["warm"] = warm
    rec["argv"] = argv_of(0)
    if fresh:
        fresh()
    rec["timeline"] = timeline(argv_of(reps + 2))
    if perf:
        if fresh:
            fresh()
        slug = re.sub(r"[^a-z0-9]+", "-", name.lower())[:40].strip("-")
        rec["perf"] = perf_profile(argv_of(reps + 1), os.path.join(work, slug + ".perf.data"))
    return rec


def fmt_run(r):
    return "%.2f | %.2f | %.2f | %.0f" % r


def report(recs, args, load):
    out = []
    out.append("# Whole commands: wall time and where it goes\n")
    out.append("Run: %s UTC on %s, %d online CPUs, Linux %s; load average before the run %s; "
               "`bench/whole_commands.py --reps %d`.\n" %
               (time.strftime("%Y-%m-%d %H:%M", time.gmtime()), cpu_name(), os.cpu_count(),
                platform.release(), load, args.reps))
    out.append("Cold: the page cache dropped just before (`echo 3 > /proc/sys/vm/drop_caches`), "
               "so the inputs are read from disk; warm: the inputs already in the page cache "
               "(median of %d runs). Outputs go to %s (page cache, written back by the kernel "
               "after the command ends).\n" % (args.reps, args.work))
    out.append("| command | cache | wall (s) | user (s) | system (s) | peak RSS (MiB) |")
    out.append("|---|---|--:|--:|--:|--:|")
    for r in recs:
        cold = "cold" if r["dropped"] else "first run (cache not dropped: not root)"
        out.append("| %s | %s | %s |" % (r["name"], cold, fmt_run(r["cold"])))
        med = tuple(statistics.median(w[k] for w in r["warm"]) for k in range(4))
        out.append("| %s | warm | %s |" % (r["name"], fmt_run(med)))
    out.append("")
    for r in recs:
        out.append("## %s\n" % r["name"])
        out.append("`%s`\n" % " ".join(os.path.relpath(a, SOURCE) if a.startswith(SOURCE) else a
                                         for a in r["argv"]))
        steps, total = r["timeline"]
        out.append("Wall time by step, from the command's own progress lines (one warm run, "
                   "%.2f s in all; each line's time runs until the next line):\n" % total)
        out.append("| step (the progress line that starts it) | seconds | share |")
        out.append("|---|--:|--:|")
        for secs, line in steps:
            if secs >= 0.02 * total:
                out.append("| %s | %.2f | %.0f %% |" %
                           (line.replace("|", "\\|")[:110], secs, 100 * secs / total))
        out.append("")
        prof = r.get("perf")
        if not prof:
            out.append("(no perf profile: perf missing or not permitted)\n")
            continue
        rows, stages = prof
        out.append("Self time by stage (perf, cpu-clock at 1999 Hz, all threads, one warm run):\n")
        out.append("| stage | share of CPU time |")
        out.append("|---|--:|")
        for st, pct in sorted(stages.items(), key=lambda kv: -kv[1]):
            if pct >= 0.5:
                out.append("| %s | %.1f %% |" % (st, pct))
        out.append("")
        out.append("Top functions (self time):\n")
        out.append("| function (library) | share | stage |")
        out.append("|---|--:|---|")
        for pct, dso, sym in rows[:15]:
            out.append("| `%s` (%s) | %.1f %% | %s |" % (sym[:70], dso, pct, stage_of(dso, sym)))
        out.append("")
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kogei", default=os.path.join(SOURCE, "build", "cli", "kogei"))
    ap.add_argument("--work", default=None, help="scratch directory (default: a new one in /tmp)")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--no-perf", action="store_true")
    ap.add_argument("-o", dest="output")
    args = ap.parse_args()
    if args.reps < 1:
        sys.exit("whole_commands: --reps must be at least 1")
    kogei = os.path.abspath(args.kogei)
    if not os.access(kogei, os.X_OK):
        sys.exit("whole_commands: %s: not an executable (build first, or pass --kogei)" % kogei)
    load = "%.2f %.2f %.2f" % os.getloadavg()
    args.work = args.work or tempfile.mkdtemp(prefix="kogei-whole-")
    work = args.work
    os.makedirs(work, exist_ok=True)
    demo = os.path.join(work, "demo")
    if not os.path.exists(os.path.join(demo, "site", "camera.json")):
        print("whole_commands: kogei demo -> %s" % demo, file=sys.stderr)
        run([kogei, "demo", "-o", demo])
    img = os.path.join(work, "photo12.tif")
    if not os.path.exists(img):
        print("whole_commands: a 12 Mpix photograph -> %s" % img, file=sys.stderr)
        run([kogei, "sim", "image", "--materials", "default",
             "--camera", os.path.join(SOURCE, "fixtures", "demo", "site_camera.csv"),
             "--illuminant", "A", "--angle", "30", "--patch-size", "500", "--size", "4000x3000",
             "--depth", "16", "--noise", "20000:5:12", "-o", img])
    calib = os.path.join(demo, "site", "camera.json")
    cube = os.path.join(work, "cube.hdr")

    def rm_cube():
        for ext in (".hdr", ".img", "_mask.hdr", "_mask.img"):
            p = cube[:-4] + ext
            if os.path.exists(p):
                os.unlink(p)

    recs = []
    print("whole_commands: kogei estimate", file=sys.stderr)
    recs.append(measure("kogei estimate, 12 Mpix 16-bit TIFF to an f32 ENVI cube (2.9 GB)",
                        lambda i: [kogei, "estimate", "--calib", calib, img, "-o", cube],
                        args.reps, not args.no_perf, work, rm_cube))
    rm_cube()
    session = os.path.join(demo, "site-session")
    ref = os.path.join(demo, "lab", "reference.json")
    print("whole_commands: kogei process", file=sys.stderr)

    def proc_out(i):
        return os.path.join(work, "process-%d" % i)

    def proc_argv(i):
        out = proc_out(i)
        if os.path.exists(out):
            shutil.rmtree(out)
        return [kogei, "process", session, "--reference", ref, "-o", out]

    recs.append(measure("kogei process of the demo's site session (800x600 object)",
                        proc_argv, args.reps, not args.no_perf, work, None))
    text = report(recs, args, load)
    sys.stdout.write(text)
    if args.output:
        tmp = args.output + ".tmp"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, args.output)


if __name__ == "__main__":
    main()
