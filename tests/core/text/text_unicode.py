#!/usr/bin/env python3
"""kogei's table of format characters (core/text.c) against Python's unicodedata: every
code point Python puts in Cf, Zl or Zp is one kogei refuses, and kogei refuses nothing
else but code points Python's (older) Unicode version has not assigned yet."""
import subprocess
import sys
import unicodedata

out = subprocess.run([sys.argv[1], "--dump"], check=True, capture_output=True, text=True)
ours = {int(x, 16) for x in out.stdout.split()}
theirs = {cp for cp in range(0x110000)
          if unicodedata.category(chr(cp)) in ("Cf", "Zl", "Zp")}
missing = sorted(theirs - ours)
extra = sorted(cp for cp in ours - theirs if unicodedata.category(chr(cp)) != "Cn")
print(f"unicodedata {unicodedata.unidata_version}: {len(theirs)} format code points, "
      f"kogei {len(ours)}")
if missing:
    print("not refused by kogei:", " ".join(f"U+{c:04X}" for c in missing[:20]))
if extra:
    print("refused by kogei, assigned otherwise:",
          " ".join(f"U+{c:04X} ({unicodedata.category(chr(c))})" for c in extra[:20]))
sys.exit(1 if missing or extra else 0)
