#!/usr/bin/env python3
"""docs/bench.md's estimation table ("Speed against error"), rebuilt from a run's
docs/bench/bench.md (kogei bench's report), and docs/bench.md's live-view table from
docs/bench/console-live.md (bench/console_live.sh), so that after bench/run_all.sh the
tables are the run's numbers and nothing else.

  bench/readme_tables.py [--bench docs/bench/bench.md] [--doc docs/bench.md]
                         [--live docs/bench/console-live.md] [--docs docs/bench.md]
                         [--check]

Without --check the page's table is replaced in place (through a temporary file and
a rename); with --check nothing is written and the exit status is 1 when the page's
table differs from what the report gives (the differing rows are printed). The
prose around the table quotes numbers by hand and must be read again after a run."""
import argparse
import os
import sys
import tempfile

METHODS = ["pca3", "pca-auto", "linear", "wiener", "rootpoly2", "rootpoly3", "lut33-pca3"]
HEADER = ("| method | f32 Mpix/s 1 / 2 threads (AVX-512) | of write limit, f32 / f16, 2 thr: "
          "AVX-512 | the same: AVX2 | f16 Mpix/s (2 thr, AVX-512) | weights Mpix/s (2 thr, "
          "AVX-512) | CC24→Munsell RMSE | ΔE00 D65 mean / p95 | ΔE00 A mean | Munsell→CES99 "
          "RMSE | ΔE00 D65 mean |")
RULE = "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|"


def cells(line):
    return [c.strip() for c in line.strip().strip("|").split("|")]


def section(lines, title):
    """The table rows (cells) following the first line equal to title."""
    try:
        at = lines.index(title)
    except ValueError:
        sys.exit(f"readme_tables: the report has no line {title!r}")
    rows, seen = [], False
    for line in lines[at + 1:]:
        if line.startswith("|"):
            seen = True
            if not line.startswith("|---"):
                rows.append(cells(line))
        elif seen:
            break
    return rows[1:]  # without the header


def speed_rows(lines):
    try:
        at = lines.index("## Speed")
    except ValueError:
        sys.exit("readme_tables: the report has no '## Speed' section")
    out = {}
    for line in lines[at + 1:]:
        if line.startswith("## "):
            break
        if line.startswith("| ") and not line.startswith("| method"):
            c = cells(line)
            if len(c) == 10:
                out[(c[0], c[1], c[2])] = c
    return out


def error_rows(lines, title):
    return {r[0]: r for r in section(lines, title)}


def build(report):
    lines = [l.rstrip("\n") for l in report]
    sp = speed_rows(lines)
    cc = error_rows(lines, "**train CC24 -> test Munsell (1269 samples), with noise**")
    ce = error_rows(lines, "**train Munsell -> test CES99 (99 samples), with noise**")

    def get(method, output, path, col):
        r = sp.get((method, output, path))
        return r[col] if r else None

    rows = [HEADER, RULE]
    for m in METHODS:
        if m not in cc or m not in ce:
            sys.exit(f"readme_tables: the report's error tables have no row {m}")
        f32_1 = get(m, "f32-bsq", "avx512", 4)
        f32_2 = get(m, "f32-bsq", "avx512", 5)
        if f32_1 is None:
            sys.exit(f"readme_tables: the report has no {m} f32-bsq avx512 row")
        share = lambda path: (f"{get(m, 'f32-bsq', path, 9) or '–'} / "
                              f"{get(m, 'f16-bsq', path, 9) or '–'}")
        w = get(m, "weights", "avx512", 5)
        rows.append("| " + " | ".join([
            m, f"{f32_1} / {f32_2}", share("avx512"), share("avx2+fma"),
            get(m, "f16-bsq", "avx512", 5) or "–",
            f"{float(w):.0f}" if w else "–",
            cc[m][1], f"{cc[m][3]} / {cc[m][4]}", cc[m][5], ce[m][1], ce[m][3]]) + " |")
    return rows


LIVE_HEADER = ("| camera | preview | page previews/s | latency median / p95 ms | console CPU ms "
               "per preview: camera, bin + focus, display + encode | load average |")


def replace_table(path, header, table, check):
    """Replace the table under header in path by table (header included); with check,
    print the differences and return 1 when there are some. 0 when path has no such
    table (nothing to do)."""
    with open(path, encoding="utf-8") as f:
        text = f.read().split("\n")
    if header not in text:
        return 0
    at = text.index(header)
    end = at
    while end < len(text) and text[end].startswith("|"):
        end += 1
    old = text[at:end]
    if check:
        diff = [(o, n) for o, n in zip(old, table) if o != n]
        if len(old) != len(table):
            diff.append((f"{len(old)} lines", f"{len(table)} lines"))
        for o, n in diff:
            print(f"{path}:  {o}\nreport:  {n}")
        return 1 if diff else 0
    text[at:end] = table
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(os.path.abspath(path)), prefix=".tables.")
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write("\n".join(text))
    os.replace(tmp, path)
    return 0


def live_table(report):
    """The live-view table of bench/console_live.sh's report, as it is."""
    lines = [l.rstrip("\n") for l in report]
    if LIVE_HEADER not in lines:
        sys.exit("readme_tables: the live-view report has no table (its header changed?)")
    at = lines.index(LIVE_HEADER)
    end = at
    while end < len(lines) and lines[end].startswith("|"):
        end += 1
    return lines[at:end]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bench", default="docs/bench/bench.md")
    ap.add_argument("--doc", "--readme", dest="readme", default="docs/bench.md")
    ap.add_argument("--live", default="docs/bench/console-live.md",
                    help="bench/console_live.sh's report (skipped when absent)")
    ap.add_argument("--docs", default="docs/bench.md",
                    help="where the live-view table goes (under its header)")
    ap.add_argument("--check", action="store_true")
    a = ap.parse_args()
    live_rc = 0
    if os.path.exists(a.live):
        with open(a.live, encoding="utf-8") as f:
            live_rc = replace_table(a.docs, LIVE_HEADER, live_table(f), a.check)
    with open(a.bench, encoding="utf-8") as f:
        table = build(f)
    with open(a.readme, encoding="utf-8") as f:
        readme = f.read().split("\n")
    try:
        at = readme.index(HEADER)
    except ValueError:
        sys.exit(f"readme_tables: {a.readme} has no estimation table (its header changed?)")
    end = at
    while end < len(readme) and readme[end].startswith("|"):
        end += 1
    old = readme[at:end]
    if a.check:
        diff = [(o, n) for o, n in zip(old, table) if o != n]
        if len(old) != len(table):
            diff.append((f"{len(old)} lines", f"{len(table)} lines"))
        for o, n in diff:
            print(f"page:    {o}\nreport:  {n}")
        return 1 if diff or live_rc else 0
    readme[at:end] = table
    d = os.path.dirname(os.path.abspath(a.readme))
    fd, tmp = tempfile.mkstemp(dir=d, prefix=".readme.")
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write("\n".join(readme))
    os.replace(tmp, a.readme)
    return 0


if __name__ == "__main__":
    sys.exit(main())
