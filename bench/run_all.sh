#!/bin/sh
# Every benchmark of docs/bench.md, one after the other in one run, into docs/bench/
# (or OUTDIR), so that its tables come from the same machine on the same day.
# A program, never a test: it asserts nothing about speed.
#
#   bench/run_all.sh [BUILD_DIR [OUTDIR]]
#
# BUILD_DIR defaults to build (built with scripts/test.sh or ninja). Needs root for
# the camera benchmark's private network namespace (unshare -rn works unprivileged
# too where user namespaces are allowed) and for dropping the page cache in the
# whole-command runs (without it the cold rows say so). Progress goes to standard
# error; each benchmark's report is written to OUTDIR. Takes about 35 minutes on two
# cores; run it on an otherwise idle machine.
set -eu
cd "$(dirname "$0")/.."
BUILD=${1:-build}
OUT=${2:-docs/bench}
mkdir -p "$OUT"
KOGEI="$BUILD/cli/kogei"
[ -x "$KOGEI" ] || { echo "run_all: $KOGEI not built (run ninja -C $BUILD)" >&2; exit 1; }
step() { echo "run_all: $(date -u +%H:%M:%S) $*" >&2; }

{
	echo "# One run of every benchmark"
	echo
	echo "$(date -u '+%Y-%m-%d %H:%M UTC'); $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'),"
	echo "$(nproc) online CPUs, flags: $(grep -o -w -E 'avx512f|avx2|fma' /proc/cpuinfo | sort -u | tr '\n' ' ')"
	echo "load average at the start: $(cut -d' ' -f1-3 /proc/loadavg); kernel $(uname -r)."
} > "$OUT/run.md"

step "kogei bench (speed against error, camera-space matching)"
"$KOGEI" bench -o "$OUT"
step "kogei bench, camera-space angles every 10 degrees"
"$KOGEI" bench --no-error --no-speed --camspace-step 10 -o "$OUT/camspace10"
"$BUILD/bench/kogei-bench-cs-search" > "$OUT/cs-search.md"
step "estimation kernels (every path)"
for isa in avx512 avx2 c; do
	"$BUILD/bench/kogei-bench-kernels" --isa "$isa" --methods 2 --json "$OUT/kernels-$isa.json" \
		> "$OUT/kernels-$isa.md" 2>>"$OUT/run.md" || echo "(no $isa path on this CPU)" > "$OUT/kernels-$isa.md"
done
step "labels (whole kogei classify)"
"$BUILD/bench/kogei-bench-labels" --kogei "$KOGEI" -o "$OUT/labels.md" >/dev/null
step "chart detection"
"$BUILD/bench/kogei-bench-chart" --kogei "$KOGEI" --json "$OUT/chart.json" > "$OUT/chart.md"
step "TIFF reading (compressed layouts, one thread and several)"
"$BUILD/bench/kogei-bench-tiff" --kogei "$KOGEI" > "$OUT/tiff.md"
step "renderer"
"$BUILD/bench/render/kogei-bench-render" -o "$OUT/render.md" >/dev/null
"$BUILD/bench/render/kogei-bench-ply" > "$OUT/ply.md"
step "cameras (Aravis fake GigE camera, private network namespace)"
if [ -x "$BUILD/bench/camera/kogei-bench-camera" ]; then
	"$BUILD/bench/camera/kogei-bench-camera" -o "$OUT/camera.md" >/dev/null ||
		echo "run_all: camera benchmark failed (see above)" >&2
fi
step "console live view (headless Chromium, private network namespace)"
unshare -rn sh -c 'ip link set lo up; sh bench/console_live.sh "$0" "$1" 20' "$KOGEI" \
	"$OUT/console-live.md" || echo "run_all: console live view benchmark failed" >&2
step "whole commands"
python3 bench/whole_commands.py --kogei "$KOGEI" -o "$OUT/whole.md" >/dev/null
step "a collection: one kogei process by stage, objects per hour (local, single-node Slurm)"
python3 bench/collection_throughput.py --kogei "$KOGEI" -o "$OUT/collection.md" >/dev/null ||
	echo "run_all: collection benchmark failed (see above)" >&2
step "done: $OUT"
echo "finished $(date -u '+%H:%M UTC'), load average $(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/run.md"
