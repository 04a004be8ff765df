#!/bin/sh
# kogei process keeps its memory bounded whatever the image size: a session recorded
# with the sim devices (dark, flat, chart, object at 800x600) has its captures'
# outputs resampled to 15000 x 10000 (150 Mpix; upscale_image keeps the CFA) and its
# manifest updated (sizes, sha256), then kogei process --cube none runs on it with its
# peak resident memory measured (the child's ru_maxrss): it must stay under 1 GiB,
# where the object alone as float RGB would take 1.8 GB and its variance as much. The
# labels must agree with those of the 800x600 session, resampled the same way, on
# most pixels (the chart is binned for detection at this size, and the demosaicing
# sees larger blocks). Needs about 8 GB of free disk. Skipped under AddressSanitizer,
# whose own memory would be measured.
# usage: test_process_memory.sh KOGEI SOURCE_ROOT UPSCALE HAVE_TAGS_AND_DEMOSAIC ASAN
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
FIX=$2/fixtures
UPSCALE=$3
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${4:-1}" numpy
[ "${5:-0}" != 1 ] || kg_skip "built with AddressSanitizer, whose own memory would be measured"
kg_temp
free_kb=$(df -Pk "$T" | awk 'NR == 2 { print $4 }')
[ "$free_kb" -gt 8000000 ] || kg_skip "less than 8 GB free in $T"
W=15000 H=10000

sim_scenes "$T" || { echo "FAIL: simulated scenes"; exit 1; }
S=$T/small
sim_acquire "$S" dark "$T/chart.tif" 10000 '&light=0' &&
sim_acquire "$S" flat "$T/chart.tif" 10000 '&uniform=0.6' &&
sim_acquire "$S" chart "$T/chart.tif" 10000 '' --layout cie-tcs-frame &&
sim_acquire "$S" object "$T/object.tif" 10000 '' --name object ||
	{ echo "FAIL: recording the session"; exit 1; }
sim_measure "$T/chart.cgats" || { echo "FAIL: measuring the chart"; exit 1; }
"$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/small-out" --cube none \
	--no-render --quiet || { echo "FAIL: kogei process of the small session"; exit 1; }

# The large session: every capture output resampled, the manifest updated.
B=$T/big
cp -r "$S" "$B" && rm -f "$B/.lock"
"$PY" - "$B" "$UPSCALE" "$W" "$H" <<'PY' || { echo "FAIL: making the large session"; exit 1; }
import hashlib, json, subprocess, sys
b, up, w, h = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
m = json.load(open(b + "/session.json"))
for c in m["captures"]:
    f = c["settings"]["format"]
    f["width"], f["height"], f["stride"] = int(w), int(h), int(w) * 2
    for o in c.get("outputs", {}).values():
        p = b + "/" + o["file"]
        subprocess.run([up, p, p + ".big", w, h], check=True)
        subprocess.run(["mv", p + ".big", p], check=True)
        o["sha256"] = hashlib.sha256(open(p, "rb").read()).hexdigest()
json.dump(m, open(b + "/session.json", "w"), indent=1)
PY

"$PY" - "$KOGEI" "$B" "$T" <<'PY'
import os, resource, subprocess, sys
kogei, b, t = sys.argv[1:4]
r = subprocess.run([kogei, "process", b, "--spectra", t + "/chart.cgats", "-o", t + "/big-out",
                    "--cube", "none", "--no-render"], stderr=subprocess.PIPE, text=True)
rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
lines = [l for l in r.stderr.splitlines() if "binned" in l or "labels written" in l]
print("\n".join(lines))
print("kogei process of a 15000 x 10000 session (--cube none): exit %d, peak RSS %.1f MiB"
      % (r.returncode, rss / 1024))
if r.returncode:
    print(r.stderr[-3000:])
sys.exit(0 if r.returncode == 0 and 0 < rss < 1024 * 1024 else 1)
PY
[ $? = 0 ] || { echo "FAIL: kogei process of the large session, or its memory"; exit 1; }

"$PY" - "$T/small-out/object" "$T/big-out/object" "$W" "$H" <<'PY' || exit 1
import json, sys, numpy as np
small, big, W, H = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
s = np.fromfile(small + "/labels.img", dtype=np.uint8).reshape(600, 800)
b = np.fromfile(big + "/labels.img", dtype=np.uint8)
assert b.size == W * H, b.size
b = b.reshape(H, W)
ys, xs = np.arange(H) * 600 // H, np.arange(W) * 800 // W
agree = np.mean(b == s[ys][:, xs])
print("labels of the large session agree with the small session's on %.4f of the pixels" % agree)
assert agree > 0.95, agree
j = json.load(open(big + "/labels.json"))
assert j["width"] == W and j["height"] == H
PY
echo "process-memory: passed"
