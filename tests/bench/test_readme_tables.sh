#!/bin/sh
# The estimation table of docs/bench.md is docs/bench/bench.md's numbers (bench/readme_tables.py
# --check), and the check notices a changed number in the report.
set -eu
SRC=$1
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
python3 "$SRC/bench/readme_tables.py" --check --bench "$SRC/docs/bench/bench.md" \
	--readme "$SRC/docs/bench.md" || { echo "FAIL: the estimation table of docs/bench.md is not docs/bench/bench.md's (run bench/readme_tables.py)"; exit 1; }
# one number of the report changed: pca3's AVX-512 f32 rate on two threads
awk -F'|' -v OFS='|' '$2==" pca3 " && $3==" f32-bsq " && $4==" avx512 " {$7=" 1.5 "} {print}' \
	"$SRC/docs/bench/bench.md" > "$TMP/bench.md"
cmp -s "$TMP/bench.md" "$SRC/docs/bench/bench.md" && { echo "FAIL: the test's change left the report as it was"; exit 1; }
if python3 "$SRC/bench/readme_tables.py" --check --bench "$TMP/bench.md" --readme "$SRC/docs/bench.md" > "$TMP/out"; then
	echo "FAIL: --check passed a report whose pca3 rate was changed"; exit 1
fi
grep -q "1.5" "$TMP/out" || { echo "FAIL: --check did not print the differing row"; cat "$TMP/out"; exit 1; }
# rewriting a copy of the page from the changed report puts the number in the table
cp "$SRC/docs/bench.md" "$TMP/page.md"
python3 "$SRC/bench/readme_tables.py" --bench "$TMP/bench.md" --readme "$TMP/page.md"
# the one-thread rate beside it is the report's, whatever the run
one=$(awk -F'|' '$2==" pca3 " && $3==" f32-bsq " && $4==" avx512 " {gsub(/ /, "", $6); print $6}' \
	"$SRC/docs/bench/bench.md")
[ -n "$one" ] || { echo "FAIL: no pca3 f32-bsq avx512 row in docs/bench/bench.md"; exit 1; }
grep -q "^| pca3 | $one / 1.5 |" "$TMP/page.md" || { echo "FAIL: the rewritten page lacks the changed rate"; exit 1; }
python3 "$SRC/bench/readme_tables.py" --check --bench "$TMP/bench.md" --readme "$TMP/page.md"
# the live-view table of docs/bench.md is docs/bench/console-live.md's, and a changed
# rate in the report is noticed
python3 "$SRC/bench/readme_tables.py" --check --bench "$SRC/docs/bench/bench.md" \
	--readme "$SRC/docs/bench.md" --live "$SRC/docs/bench/console-live.md" --docs "$SRC/docs/bench.md" ||
	{ echo "FAIL: docs/bench.md's live-view table is not docs/bench/console-live.md's"; exit 1; }
awk -F'|' -v OFS='|' '$2 ~ /^ 1024 x 768/ {$4=" 0.5 "} {print}' "$SRC/docs/bench/console-live.md" \
	> "$TMP/console-live.md"
cmp -s "$TMP/console-live.md" "$SRC/docs/bench/console-live.md" && { echo "FAIL: the live report was not changed"; exit 1; }
if python3 "$SRC/bench/readme_tables.py" --check --bench "$SRC/docs/bench/bench.md" \
	--readme "$SRC/docs/bench.md" --live "$TMP/console-live.md" --docs "$SRC/docs/bench.md" > "$TMP/out"; then
	echo "FAIL: --check passed a live report whose rate was changed"; exit 1
fi
grep -q " 0.5 " "$TMP/out" || { echo "FAIL: --check did not print the differing live row"; cat "$TMP/out"; exit 1; }
echo "readme-tables: ok"
