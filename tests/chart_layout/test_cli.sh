#!/bin/sh
# `kogei chart print` from the command line: outputs, usage errors (exit 2) and bad
# input (exit 1) with nothing left behind. $1 is the kogei program.
kogei="$1"
fail=0
dir=$(mktemp -d /tmp/kogei-chart-cli-XXXXXX)
trap 'rm -rf "$dir"' EXIT

check() { # expected-status description command...
	want=$1; what=$2; shift 2
	"$@" >"$dir/out" 2>"$dir/err"
	got=$?
	if [ "$got" -ne "$want" ]; then
		echo "FAIL: $what: exit $got, expected $want" >&2
		cat "$dir/err" >&2
		fail=1
	fi
}

if ! "$kogei" chart print --layout colorchecker24-frame -o "$dir/probe.svg" 2>"$dir/err"; then
	if grep -q libapriltag "$dir/err"; then
		echo "SKIP: kogei built without libapriltag (refusal message checked)"
		exit 77
	fi
	cat "$dir/err" >&2
	exit 1
fi

check 0 "help" "$kogei" chart print --help
grep -q -- "--layout" "$dir/out" || { echo "FAIL: --help lacks --layout" >&2; fail=1; }
check 0 "bundled name to svg" "$kogei" chart print --layout colorchecker-sg-frame -o "$dir/sg.svg"
head -c 5 "$dir/sg.svg" | grep -q '<?xml' || { echo "FAIL: sg.svg is not XML" >&2; fail=1; }
check 0 "file to pdf" "$kogei" chart print --layout "$KOGEI_SOURCE_ROOT/fixtures/charts/colorchecker-passport-frame.json" -o "$dir/pp.pdf"
head -c 5 "$dir/pp.pdf" | grep -q '%PDF-' || { echo "FAIL: pp.pdf is not PDF" >&2; fail=1; }
check 0 "png at 40 dpi" "$kogei" chart print --layout colorchecker24-frame -o "$dir/cc.png" --dpi 40
if [ -f /usr/share/color/argyll/ref/ColorChecker.cht ]; then
	check 0 ".cht with --width" "$kogei" chart print --layout /usr/share/color/argyll/ref/ColorChecker.cht --width 279.4 -o "$dir/cht.svg"
	check 1 ".cht without --width" "$kogei" chart print --layout /usr/share/color/argyll/ref/ColorChecker.cht -o "$dir/cht2.svg"
	grep -q "template units" "$dir/err" || { echo "FAIL: message lacks 'template units'" >&2; fail=1; }
fi

check 2 "no layout" "$kogei" chart print -o "$dir/x.svg"
check 2 "no output" "$kogei" chart print --layout colorchecker24-frame
check 2 "stdout" "$kogei" chart print --layout colorchecker24-frame -o -
check 2 "bad dpi" "$kogei" chart print --layout colorchecker24-frame -o "$dir/x.png" --dpi 0
check 2 "extra argument" "$kogei" chart print --layout colorchecker24-frame -o "$dir/x.svg" extra
check 1 "unknown layout" "$kogei" chart print --layout no-such-layout -o "$dir/x.svg"
check 1 "unknown format" "$kogei" chart print --layout colorchecker24-frame -o "$dir/x.jpg"
check 1 "--width on json" "$kogei" chart print --layout colorchecker24-frame --width 100 -o "$dir/x.svg"
for f in x.svg x.png x.jpg cht2.svg; do
	[ -e "$dir/$f" ] && { echo "FAIL: $f left behind" >&2; fail=1; }
done
ls -A "$dir" | grep -q '\.tmp\|~' && { echo "FAIL: temporary file left" >&2; fail=1; }
[ $fail -eq 0 ] && echo "chart-print-cli: ok"
exit $fail
