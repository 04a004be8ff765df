#!/bin/sh
# Symbolic links out of a session (docs/acquire.md): with frames/, captures/,
# captures/NAME or frames/index.jsonl a link to a folder or file elsewhere, `kogei
# acquire` exits 1 with a message naming the link, and writes nothing outside the
# session (the folder the link points at stays empty, the linked index unchanged).
# Also: --layout FILE is copied into captures/NAME/layout.json and the manifest names
# that copy, not the file outside.
set -u
. "$(dirname "$0")/../lib.sh"
kogei=$1
layout=$2
kg_temp
tmp=$T
cam='sim:?width=32&height=24'
acq() { "$kogei" acquire --camera "$cam" --out "$1" --kind object --frames 1 --exposure 1000 \
	${2:+--name "$2"} >"$tmp/out" 2>"$tmp/err"; }
empty() { [ -z "$(ls -A "$1")" ]; }

# 1: frames/, captures/ of a new session each a link to a folder elsewhere
for sub in frames captures; do
	s="$tmp/s-$sub" o="$tmp/outside-$sub"
	mkdir -p "$s" "$o"
	ln -s "$o" "$s/$sub"
	acq "$s"
	rc=$?
	check_eval "$sub linked: exit 1 (got $rc)" '[ $rc -eq 1 ]'
	check_eval "$sub linked: the message names the link" \
		'grep -q "$s/$sub: is a symbolic link" "$tmp/err"'
	check_eval "$sub linked: nothing written outside" 'empty "$o"'
done

# 2: an existing session; then captures/NAME, frames/NAME and frames/index.jsonl links
base="$tmp/base"
acq "$base"
rc=$?
check_eval "first capture: exit 0 (got $rc: $(cat "$tmp/err"))" '[ $rc -eq 0 ]'
for case in captures/object-0002 captures/mine frames/mine; do
	s="$tmp/s-$(echo "$case" | tr / _)" o="$tmp/outside-$(echo "$case" | tr / _)"
	rm -rf "$s"
	cp -a "$base" "$s"
	mkdir -p "$o"
	ln -s "$o" "$s/$case"
	cp "$s/session.json" "$tmp/manifest.before"
	acq "$s"                   # the next free name
	rc1=$?
	acq "$s" "${case##*/}"     # the link's own name
	rc2=$?
	check_eval "$case linked: exit 1 and 1 (got $rc1, $rc2)" '[ $rc1 -eq 1 ] && [ $rc2 -eq 1 ]'
	check_eval "$case linked: the message names the link" \
		'grep -q "$s/$case: is a symbolic link" "$tmp/err"'
	check_eval "$case linked: nothing written outside" 'empty "$o"'
	check_eval "$case linked: the manifest unchanged" 'cmp -s "$s/session.json" "$tmp/manifest.before"'
done
# a dangling link (to a folder that does not exist yet) is refused too
s="$tmp/s-dangling"
cp -a "$base" "$s"
ln -s "$tmp/not-yet" "$s/captures/object-0002"
acq "$s"
rc=$?
check_eval "dangling captures/NAME: exit 1 (got $rc)" '[ $rc -eq 1 ]'
check_eval "dangling captures/NAME: nothing created outside" '[ ! -e "$tmp/not-yet" ]'

# .lock a link to a file elsewhere: not opened through (nothing created there)
s="$tmp/s-lock"
cp -a "$base" "$s"
rm -f "$s/.lock"
ln -s "$tmp/lock-outside" "$s/.lock"
acq "$s"
rc=$?
check_eval ".lock linked: exit 1 (got $rc)" '[ $rc -eq 1 ]'
check_eval ".lock linked: nothing created outside" '[ ! -e "$tmp/lock-outside" ]'

# 3: frames/index.jsonl a link to a file elsewhere: not appended through
s="$tmp/s-index"
cp -a "$base" "$s"
cp "$s/frames/index.jsonl" "$tmp/index-outside"
cp "$tmp/index-outside" "$tmp/index-outside.before"
rm "$s/frames/index.jsonl"
ln -s "$tmp/index-outside" "$s/frames/index.jsonl"
acq "$s"
rc=$?
check_eval "index.jsonl linked: exit 1 (got $rc)" '[ $rc -eq 1 ]'
check_eval "index.jsonl linked: the message names the link" \
	'grep -q "$s/frames/index.jsonl: is a symbolic link" "$tmp/err"'
check_eval "index.jsonl linked: the file outside unchanged" \
	'cmp -s "$tmp/index-outside" "$tmp/index-outside.before"'
check_eval "index.jsonl linked: no capture added" '[ ! -e "$s/captures/object-0002" ]'

# 4: --layout FILE: a copy inside the session, which the manifest names
s="$tmp/s-layout"
cp "$layout" "$tmp/my-layout.json"
"$kogei" acquire --camera "$cam" --out "$s" --kind chart --frames 1 --exposure 1000 \
	--layout "$tmp/my-layout.json" >"$tmp/out" 2>"$tmp/err"
rc=$?
check_eval "--layout FILE: exit 0 (got $rc: $(cat "$tmp/err"))" '[ $rc -eq 0 ]'
check_eval "--layout FILE: copied into captures/chart-0001/layout.json" \
	'cmp -s "$s/captures/chart-0001/layout.json" "$layout"'
check_eval "--layout FILE: the manifest names the copy" \
	'grep -q "\"chart_layout\": *\"captures/chart-0001/layout.json\"" "$s/session.json"'
check_eval "--layout FILE: the manifest names no file outside as the layout" \
	'! grep -q "\"chart_layout\": *\"$tmp" "$s/session.json"'
# and the session so recorded still opens (a second capture)
acq "$s"
rc=$?
check_eval "a session with a copied layout opens: exit 0 (got $rc: $(cat "$tmp/err"))" '[ $rc -eq 0 ]'

[ $fail -eq 0 ] && echo "acquire-links: all checks passed"
exit $fail
