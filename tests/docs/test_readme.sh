#!/bin/sh
# The README as a newcomer meets it: at most 250 lines, every relative link in it and
# in docs/ points at a file of the tree, and its first session runs as written, from
# a folder outside the checkout, with `kogei` on the PATH, into the folder it names.
# Usage: test_readme.sh KOGEI SRC
set -eu
KOGEI=$(realpath "$1")
SRC=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

n=$(wc -l < "$SRC/README.md")
[ "$n" -le 250 ] || fail "README.md has $n lines (at most 250)"
echo "README.md: $n lines"

python3 - "$SRC" <<'PY' || exit 1
import os, re, sys
src = sys.argv[1]
pages = [os.path.join(src, "README.md")]
pages += [os.path.join(src, "docs", f) for f in sorted(os.listdir(os.path.join(src, "docs")))
          if f.endswith(".md")]
def anchors(path):
    """The anchors of a Markdown page's headings, as GitHub makes them: lower case,
    punctuation but '-' and '_' dropped, spaces to '-', repeats numbered -1, -2..."""
    text = re.sub(r"```.*?```", "", open(path, encoding="utf-8").read(), flags=re.S)
    seen, out = {}, set()
    for m in re.finditer(r"^#{1,6}\s+(.*?)\s*#*\s*$", text, flags=re.M):
        slug = re.sub(r"[^\w\- ]", "", m.group(1).strip().lower()).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out

bad = nanchors = 0
for page in pages:
    text = open(page, encoding="utf-8").read()
    # links and images outside code spans and fences
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    for m in re.finditer(r"!?\[[^\]]*\]\(([^)\s]+)\)", text):
        target = m.group(1).strip("`<>")
        if re.match(r"[a-z]+:", target):
            continue
        file, _, frag = target.partition("#")
        path = os.path.normpath(os.path.join(os.path.dirname(page), file)) if file else page
        if not os.path.exists(path):
            print(f"FAIL: {os.path.relpath(page, src)}: link to {target}: no such file")
            bad += 1
        elif not path.startswith(os.path.realpath(src) + os.sep) and not path.startswith(src + os.sep):
            print(f"FAIL: {os.path.relpath(page, src)}: link to {target} leaves the repository")
            bad += 1
        elif frag and path.endswith(".md"):
            nanchors += 1
            if frag not in anchors(path):
                print(f"FAIL: {os.path.relpath(page, src)}: link to {target}: "
                      f"{os.path.relpath(path, src)} has no heading with that anchor")
                bad += 1
print(f"links: {len(pages)} pages checked, {nanchors} anchors among the links, {bad} broken")
sys.exit(1 if bad else 0)
PY

# nothing a reader is given sends them outside the repository: pages, fixture READMEs
# and every command's --help (tests and benchmarks may still read the reference data)
out=$(grep -n -e '\.\./shared' -e 'DESIGN\.md' -e 'NOTES\.md' -e 'STYLE\.md' \
	"$SRC/README.md" "$SRC"/docs/*.md "$SRC"/fixtures/*/README.md 2>/dev/null || true)
[ -z "$out" ] || fail "a page points outside the repository: $out"
for c in "" demo acquire measure console process report "chart print" "chart detect" \
	"calib reference" "calib camera" estimate classify "materials learn" render export \
	"spectra xyz" model "sim patches" "sim image" "sim chart" devices bench deposit \
	"collection run" "collection status"; do
	# shellcheck disable=SC2086
	"$KOGEI" $c --help > "$T/help" 2>&1 || true
	[ -s "$T/help" ] || fail "kogei $c --help printed nothing"
	if grep -n -e '\.\./shared' -e 'DESIGN\.md' "$T/help"; then
		fail "kogei $c --help points outside the repository (above)"
	fi
done
echo "help texts and pages: nothing points outside the repository"

# the first session: the shell block after "## A first session", run as it stands but
# for the folder it makes (~/first-session); it must not need to know where the
# checkout is (bundled data by name: demo-site, cie-tcs-frame, default)
awk '/^## A first session/{s=1} s&&/^```sh/{b=1;next} b&&/^```/{exit} b{print}' \
	"$SRC/README.md" > "$T/session.sh"
grep -q "kogei process" "$T/session.sh" || fail "README: no shell block with kogei process under '## A first session'"
if grep -n -e '~/kogei' -e 'fixtures/' "$T/session.sh"; then
	fail "README's session names a path inside the checkout (above): a reader's checkout may be anywhere"
fi
sed -i "s#~/first-session#$T/first-session#g" "$T/session.sh"
mkdir "$T/elsewhere"
cd "$T/elsewhere"
PATH="$(dirname "$KOGEI"):$PATH" sh -eu "$T/session.sh" > "$T/log" 2>&1 ||
	{ if grep -q "which this kogei was built without" "$T/log"; then
		echo "SKIP: the README's first session needs a feature this build lacks: $(grep -m1 'built without' "$T/log")"
		exit 77
	fi
	tail -20 "$T/log"; fail "the README's first session failed"; }
R="$T/first-session/results"
for f in report.html process.json conformance.json camera.json camera.icc camera.ti3 \
	object-0001/cube.hdr object-0001/labels.hdr object-0001/master.tif; do
	[ -s "$R/$f" ] || fail "the README's session did not write results/$f"
done
[ -z "$(ls -A "$T/elsewhere")" ] || fail "the session wrote into the folder it ran from: $(ls -A "$T/elsewhere")"
python3 - "$R/process.json" <<'PY' || exit 1
import json, sys
p = json.load(open(sys.argv[1]))
text = json.dumps(p)
for v in ("2026.1.1", "2026.1.2", "Alloy coupons", "tungsten, 45 degrees"):
    if v not in text:
        sys.exit(f"FAIL: process.json lacks the record {v!r} the README's session gives")
accs = [o.get("meta", {}).get("accession") for o in p["objects"]]
if accs != ["2026.1.1", "2026.1.2"]:
    sys.exit(f"FAIL: the README's two objects carry accessions {accs}")
PY
B="$T/first-session/bag"
[ -s "$B/bagit.txt" ] && [ -s "$B/manifest-sha512.txt" ] || fail "the README's session wrote no bag"
for a in 2026.1.1 2026.1.2; do
	grep -q "^External-Identifier: $a\$" "$B/bag-info.txt" || fail "bag-info.txt lacks External-Identifier $a"
done
echo "the README's first session: ok ($(grep -c '' "$T/session.sh") lines)"

# "## A collection": its CSV block as list.csv in the first session's folder and its
# shell block run there: the session processed again into collection/S, the same cube
s_csv=$(awk '/^## A collection/{s=1} s&&/^```$/{b=!b;if(!b)exit;next} s&&b{print}' "$SRC/README.md")
awk '/^## A collection/{s=1} s&&/^```sh/{b=1;next} b&&/^```/{exit} b{print}' \
	"$SRC/README.md" > "$T/collection.sh"
grep -q "kogei collection run" "$T/collection.sh" || fail "README: no shell block with kogei collection run under '## A collection'"
[ -n "$s_csv" ] || fail "README: no CSV block under '## A collection'"
cd "$T/first-session"
printf '%s\n' "$s_csv" > list.csv
PATH="$(dirname "$KOGEI"):$PATH" sh -eu "$T/collection.sh" > "$T/log" 2>&1 ||
	{ tail -20 "$T/log"; fail "the README's collection failed"; }
python3 - collection/collection.json <<'PY' || exit 1
import json, sys
r = json.load(open(sys.argv[1]))
objs = [o for e in r["entries"] for o in e["objects"]]
if r["counts"]["done"] != 1 or [o["accession"] for o in objs] != ["2026.1.1", "2026.1.2"]:
    sys.exit(f"FAIL: the README's collection: counts {r['counts']}, objects {objs}")
if not all(o["meta"].get("lighting") == "tungsten at 45 degrees" for o in objs):
    sys.exit("FAIL: the README's collection: the list's meta.lighting is not on every object")
PY
cmp -s results/object-0001/cube.img collection/S/object-0001/cube.img ||
	fail "the README's collection: its cube differs from the first session's"
echo "the README's collection: ok"
