#!/bin/sh
# kogei chart detect on an uncompressed 16-bit TIFF (read through a mapping) that another
# program cuts short while it is mapped (cut_preload.c, right after the mapping is made;
# and, without the shim, by `truncate` at random moments of real runs): the command never
# dies of a signal (SIGBUS), exits 1 naming the file and what happened, and writes no
# patch file. The same run on the whole file passes.
# usage: test_map_cut.sh KOGEI SHIM
set -u
KOGEI=$1 SHIM=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail=0
"$KOGEI" sim chart --layout colorchecker24-frame --camera demo-site --illuminant D65 \
	--width 3000 --height 2000 --depth 16 --noise none -o "$T/chart.tif" >/dev/null 2>&1 ||
	{ echo "FAIL: sim chart"; exit 1; }
"$KOGEI" chart detect --layout colorchecker24-frame "$T/chart.tif" -o "$T/whole.cgats" \
	--quiet || { echo "FAIL: chart detect of the whole file"; exit 1; }

for keep in 0.5 0.02 0.98; do
	cp "$T/chart.tif" "$T/victim.tif"
	rm -f "$T/out.cgats"
	KOGEI_CUT_NAME=victim.tif KOGEI_CUT_KEEP=$keep \
		ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0 \
		LD_PRELOAD=$SHIM "$KOGEI" chart detect --layout colorchecker24-frame \
		"$T/victim.tif" -o "$T/out.cgats" --quiet 2>"$T/err"
	rc=$?
	grep -q "cut_preload: .* cut to" "$T/err" || { echo "FAIL: keep $keep: the shim cut nothing"; cat "$T/err"; fail=1; continue; }
	if [ $rc != 1 ] || ! grep -q "victim.tif: the file was cut short by another program" "$T/err"; then
		echo "FAIL: keep $keep: exit $rc, expected 1 naming the file cut short:"; cat "$T/err"; fail=1
	fi
	[ -e "$T/out.cgats" ] && { echo "FAIL: keep $keep: a patch file was written"; fail=1; }
	echo "keep $keep: exit $rc: $(grep -v cut_preload "$T/err" | head -1)"
done

# Real runs, cut by another process at random moments: no signal death, exit 0 or 1.
died=0 cut=0
for i in 1 2 3 4 5 6 7 8; do
	cp "$T/chart.tif" "$T/victim.tif"
	"$KOGEI" chart detect --layout colorchecker24-frame "$T/victim.tif" -o "$T/out.cgats" \
		--quiet 2>"$T/err" &
	pid=$!
	sleep "0.0$(( (i * 37) % 10 ))"
	truncate -s 1000000 "$T/victim.tif"
	wait $pid
	rc=$?
	[ $rc -ge 128 ] && { died=$((died + 1)); echo "FAIL: run $i died of signal $((rc - 128))"; cat "$T/err"; }
	[ $rc = 1 ] && cut=$((cut + 1))
	[ $rc -le 1 ] || fail=1
done
echo "random cuts: $cut of 8 runs refused, $died died of a signal"

[ $fail = 0 ] && echo "ok"
exit $fail
