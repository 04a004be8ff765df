#!/bin/sh
# kogei deposit (docs/deposit.md) on a small sim session of two objects whose records
# differ (accession A1 and B2), processed: the bag checked by a BagIt reader of the
# test's own (bagit_check.py: bagit.txt, every sha512 recomputed, the manifest against
# data/, the tag manifest, Payload-Oxum, Bagging-Date, both External-Identifier lines,
# the payload against RESULTS and the session file by file), without and with
# --with-session, hard-linked and copied, with a config file and options over it, a file
# name that needs percent-encoding; --verify on a good bag and after a changed byte, a
# deleted file, an added file and a changed tag file (each named); a moved session
# (found beside its results when the two moved together, else --session DIR, another
# session refused by its id); refusals (RESULTS not a process output, BAG a folder that
# is not a bag, an existing bag without --force, values with a line break, bad config
# lines, BAG inside RESULTS); interrupted deposits (SIGKILL and SIGINT mid-copy by
# strace's syscall injection, a write failing with EFBIG under ulimit -f) leave nothing
# at BAG.
# usage: test_deposit.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
FIX=$2/fixtures
CHECKER=$(dirname "$0")/bagit_check.py
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${3:-1}" json
kg_temp

sim_scenes "$T" || { echo "FAIL: simulated scenes"; exit 1; }
S=$T/S
sim_acquire "$S" chart "$T/chart.tif" 10000 '' --layout cie-tcs-frame 2>>"$T/acquire.log" || fail=1
sim_acquire "$S" object "$T/object.tif" 10000 "&seed=1" --name vase --meta accession=A1 \
	--meta title=Vase 2>>"$T/acquire.log" || fail=1
sim_acquire "$S" object "$T/object.tif" 10000 "&seed=2" --name bowl --meta accession=B2 \
	--meta operator=Kim 2>>"$T/acquire.log" || fail=1
sim_measure "$T/chart.cgats" || { echo "FAIL: kogei measure"; fail=1; }
[ $fail = 0 ] || exit 1
R=$T/results
run_or_exit "$KOGEI" process "$S" --spectra "$T/chart.cgats" --no-render --quiet --threads 1 \
	--cube f16 -o "$R"
# a file of the operator's in RESULTS whose name holds '%' and a line break
ODD=$(printf 'notes 100%%\nodd.txt')
echo "kept with the results" >"$R/$ODD"
SID=$("$PY" -c 'import json, sys; print(json.load(open(sys.argv[1]))["id"])' "$S/session.json")
ino() { stat -c %i "$1"; }
# No entry of the bag's name, hidden or not, in its folder (ALSO_HIDDEN=0: the hidden
# staging folder of a killed deposit may stay).
nothing_at() { # DIR NAME ALSO_HIDDEN
	[ ! -e "$1/$2" ] || return 1
	[ "$3" = 0 ] || [ -z "$(ls -A "$1" | grep -F ".$2.")" ]
}

# ---- a deposit of RESULTS: config, options over it, hard links -------------------------
cat >"$T/deposit.conf" <<'EOF'
# kogei deposit configuration
Source-Organization: Museum of Craft
contact-name: Nobody

Contact-Email:   conservation@example.org
EOF
B=$T/bags/one
mkdir "$T/bags"
expect_exit 0 "$KOGEI" deposit "$R" -o "$B" --config "$T/deposit.conf" --contact-name "Ann Lee"
check "deposit: a summary line" grep -q "^kogei deposit: .* 2 External-Identifier" "$T/out"
check_eval "deposit: files hard-linked on one file system" \
	'[ "$(ino "$R/process.json")" = "$(ino "$B/data/process.json")" ]'
expect_exit 0 "$PY" "$CHECKER" "$B" --id A1 --id B2 --source "$R" data \
	--info "Source-Organization: Museum of Craft" --info "Contact-Name: Ann Lee" \
	--info "Contact-Email: conservation@example.org" \
	--info "Internal-Sender-Identifier: $SID"
check "the bag holds the odd name, percent-encoded" grep -q 'notes 100%25%0Aodd.txt$' "$B/manifest-sha512.txt"
set -- $(cat "$T/out") # N FILES OCTETS
expect_exit 0 "$KOGEI" deposit --verify "$B"
check "--verify: valid with the checker's counts" grep -qx "$B: valid: $1 files, $3 bytes" "$T/out"

# ---- with the session, copied ------------------------------------------------------------
BS=$T/bags/with-session
expect_exit 0 "$KOGEI" deposit "$R" -o "$BS" --with-session --copy --source-organization "M"
check_eval "--copy: no hard link" '[ "$(ino "$R/process.json")" != "$(ino "$BS/data/results/process.json")" ]'
expect_exit 0 "$PY" "$CHECKER" "$BS" --id A1 --id B2 --source "$R" data/results \
	--source "$S" data/session --info "Source-Organization: M" --no-label Contact-Name
check "with the session: data/ holds results/ and session/ only" \
	test "$(ls "$BS/data" | tr '\n' ' ')" = "results session "
expect_exit 0 "$KOGEI" deposit --verify "$BS"

# ---- --verify of a bag changed in every way -------------------------------------------------
X=$T/bags/tampered
cp -a "$BS" "$X"
printf 'Z' | dd of="$X/data/results/vase/scene.json" bs=1 seek=20 conv=notrunc 2>/dev/null
rm "$X/data/session/session.json"
echo added >"$X/data/results/added.txt"
expect_exit 1 "$KOGEI" deposit --verify "$X"
check "--verify names the changed file" grep -q "data/results/vase/scene.json: changed" "$T/err"
check "--verify names the missing file" grep -q "data/session/session.json: missing" "$T/err"
check "--verify names the added file" grep -q "data/results/added.txt: not in manifest-sha512.txt" "$T/err"
check "--verify: the counts" grep -q "invalid: 1 missing, 1 extra, 1 changed" "$T/err"
check "--verify: nothing on standard output" test ! -s "$T/out"
cp -a "$BS" "$X.2"
sed -i 's/^Source-Organization: M$/Source-Organization: N/' "$X.2/bag-info.txt"
expect_exit 1 "$KOGEI" deposit --verify "$X.2"
check "--verify: a tag file changed is named" grep -q "bag-info.txt: changed" "$T/err"
mkdir "$T/plain" && echo x >"$T/plain/file"
expect_exit 1 "$KOGEI" deposit --verify "$T/plain"
check "--verify of a folder that is no bag" grep -q "not a bag (no bagit.txt)" "$T/err"

# ---- a moved session --------------------------------------------------------------------------
# The working folder moved whole (the session beside the results, as before): found
# there by its name and id.
mkdir "$T/nas" && mv "$S" "$R" "$T/nas/"
expect_exit 0 "$KOGEI" deposit "$T/nas/results" -o "$T/bags/nas" --with-session
expect_exit 0 "$PY" "$CHECKER" "$T/bags/nas" --id A1 --id B2 --source "$T/nas/S" data/session \
	--source "$T/nas/results" data/results
check_eval "the moved session's files are the bag's (hard links)" \
	'[ "$(ino "$T/nas/S/session.json")" = "$(ino "$T/bags/nas/data/session/session.json")" ]'
mv "$T/nas/S" "$T/nas/results" "$T/" && rm -rf "$T/nas" "$T/bags/nas"
# Moved elsewhere: --session DIR.
mv "$S" "$T/S-moved"
expect_exit 1 "$KOGEI" deposit "$R" -o "$T/bags/moved" --with-session
check "a moved session: --session asked for" grep -q "give the session's folder with --session" "$T/err"
expect_exit 0 "$KOGEI" deposit "$R" -o "$T/bags/moved" --session "$T/S-moved"
expect_exit 0 "$PY" "$CHECKER" "$T/bags/moved" --id A1 --id B2 --source "$T/S-moved" data/session
cp -a "$T/S-moved" "$T/S-other"
sed -i "s/$SID/00000000-0000-4000-8000-000000000002/" "$T/S-other/session.json"
expect_exit 1 "$KOGEI" deposit "$R" -o "$T/bags/other" --session "$T/S-other"
check "another session refused, its id named" grep -q "session id 00000000-0000-4000-8000-000000000002.*not its session" "$T/err"
check "another session: nothing written" nothing_at "$T/bags" other 1
mv "$T/S-moved" "$S"

# ---- refusals -------------------------------------------------------------------------------
expect_exit 1 "$KOGEI" deposit "$S" -o "$T/bags/x"
check "RESULTS without process.json refused" grep -q "$S: not the output of kogei process" "$T/err"
mkdir "$T/fake" && echo '{"format": "kogei-session/1"}' >"$T/fake/process.json"
expect_exit 1 "$KOGEI" deposit "$T/fake" -o "$T/bags/x"
check "a process.json of another format refused" grep -q "fake/process.json: format: expected \"kogei-process/1\"" "$T/err"
mkdir "$T/bags/mine" && echo keep >"$T/bags/mine/notes.txt"
for f in "" --force; do
	expect_exit 1 "$KOGEI" deposit "$R" -o "$T/bags/mine" $f
	check "BAG a folder that is not a bag refused ($f)" grep -q "mine: exists and is not a bag" "$T/err"
done
check "that folder untouched" test "$(ls "$T/bags/mine")" = notes.txt
expect_exit 1 "$KOGEI" deposit "$R" -o "$B"
check "an existing bag without --force refused" grep -q "one: a bag exists there; --force replaces it" "$T/err"
old=$(ino "$B/bag-info.txt")
expect_exit 0 "$KOGEI" deposit "$R" -o "$B" --force --source-organization "Second"
check_eval "--force replaced the bag" '[ "$(ino "$B/bag-info.txt")" != "$old" ]'
expect_exit 0 "$PY" "$CHECKER" "$B" --id A1 --id B2 --info "Source-Organization: Second" --no-label Contact-Email
check "--force: nothing left beside the bag" test "$(ls -A "$T/bags" | grep -c '^\.')" = 0
NL=$(printf 'Ann\nLee')
expect_exit 2 "$KOGEI" deposit "$R" -o "$T/bags/x" --contact-name "$NL"
check "a value with a line break refused, naming the option" grep -q -- "--contact-name: holds a line break" "$T/err"
CR=$(printf 'Museum\rX')
expect_exit 2 "$KOGEI" deposit "$R" -o "$T/bags/x" --source-organization "$CR"
check "a value with a CR refused, naming the option" grep -q -- "--source-organization: holds a line break" "$T/err"
printf 'Contact-Name: A\nContact-Email\n' >"$T/bad1.conf"
printf 'Payload-Oxum: 1.1\n' >"$T/bad2.conf"
printf 'Contact-Name: A\n\tcontinued\n' >"$T/bad3.conf"
printf 'Contact-Name: \033[31mred\n' >"$T/bad4.conf"
expect_exit 1 "$KOGEI" deposit "$R" -o "$T/bags/x" --config "$T/bad1.conf"
check "a config line without a colon: named" grep -q "bad1.conf: line 2: expected \"Label: value\"" "$T/err"
expect_exit 1 "$KOGEI" deposit "$R" -o "$T/bags/x" --config "$T/bad2.conf"
check "a config line of a computed label: named" grep -q "bad2.conf: line 1: Payload-Oxum is written by kogei deposit" "$T/err"
expect_exit 1 "$KOGEI" deposit "$R" -o "$T/bags/x" --config "$T/bad3.conf"
check "a folded config line: named" grep -q "bad3.conf: line 2" "$T/err"
expect_exit 1 "$KOGEI" deposit "$R" -o "$T/bags/x" --config "$T/bad4.conf"
check "a control character in a config value: named" grep -q "bad4.conf: line 1: Contact-Name: expected no control" "$T/err"
expect_exit 1 "$KOGEI" deposit "$R" -o "$R/bag"
check "BAG inside RESULTS refused" grep -q "inside RESULTS" "$T/err"
expect_exit 2 "$KOGEI" deposit --verify "$B" -o "$T/bags/x"
check "--verify with -o: a usage error" grep -q -- "--verify BAG checks a bag" "$T/err"
check "the refusals wrote nothing" nothing_at "$T/bags" x 1
check "nothing written inside RESULTS" nothing_at "$R" bag 1

# ---- interrupted deposits leave nothing at BAG --------------------------------------------------
# A write that fails (EFBIG: a file-size limit, as a full disk would): nothing at all left.
(ulimit -f 2048; trap '' XFSZ; exec "$KOGEI" deposit "$R" -o "$T/bags/full" --copy) \
	>"$T/out" 2>"$T/err"
rc=$?
check_eval "a failing write: exit 1 (got $rc)" '[ $rc = 1 ]'
check "a failing write: named" grep -q "write failed" "$T/err"
check "a failing write: nothing left" nothing_at "$T/bags" full 1
if [ "$(id -u)" != 0 ]; then
	mkdir "$T/ro" && chmod 555 "$T/ro"
	expect_exit 1 "$KOGEI" deposit "$R" -o "$T/ro/bag"
	check "a read-only parent: nothing left" test -z "$(ls -A "$T/ro")"
	chmod 755 "$T/ro"
fi
if command -v strace >/dev/null; then
	# SIGINT at the 5th write of the copy: the deposit stops, removes its staging folder and
	# ends by the signal.
	strace -f -qq -o /dev/null -e trace=write -e signal=none -e inject=write:signal=SIGINT:when=5 \
		"$KOGEI" deposit "$R" -o "$T/bags/int" --copy >"$T/out" 2>"$T/err"
	rc=$?
	check_eval "SIGINT: exit 130 (got $rc)" '[ $rc = 130 ]'
	check "SIGINT: said" grep -q "interrupted by SIGINT: nothing written" "$T/err"
	check "SIGINT: nothing left" nothing_at "$T/bags" int 1
	# SIGKILL at the 5th write: only the hidden staging folder stays; the next deposit to
	# that bag removes it.
	strace -f -qq -o /dev/null -e trace=write -e signal=none -e inject=write:signal=SIGKILL:when=5 \
		"$KOGEI" deposit "$R" -o "$T/bags/kill" --copy >/dev/null 2>&1
	check "SIGKILL: nothing named BAG" nothing_at "$T/bags" kill 0
	check "SIGKILL: its staging folder was there" test -n "$(ls -A "$T/bags" | grep -F '.kill.kogei-tmp.')"
	expect_exit 0 "$KOGEI" deposit "$R" -o "$T/bags/kill" --progress
	check "the next deposit removed the killed one's staging" grep -q "removed .*\.kill\.kogei-tmp\." "$T/err"
	check "the next deposit: a line per file" grep -q "^kogei deposit: \[1/" "$T/err"
	check "the next deposit: nothing hidden left" test -z "$(ls -A "$T/bags" | grep -F '.kill.')"
	expect_exit 0 "$KOGEI" deposit --verify "$T/bags/kill"
else
	echo "note: strace missing: the SIGINT and SIGKILL cases were not run"
fi
exit $fail
