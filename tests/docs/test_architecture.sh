#!/bin/sh
# docs/architecture.md true to the tree. The module folders are the top-level folders
# the root meson.build descends into (tests/ aside). Every .c, .cpp and .h file in
# them is named in the page by its path in backquotes (`core/cgats.c`), every such
# path the page names is a file of the tree, and every module folder has its line in
# the page's folder list ("core/      spectra ...").
# Usage: test_architecture.sh SRC
set -eu
SRC=${1:?usage: test_architecture.sh SRC}
DOC=$SRC/docs/architecture.md
fail() { echo "FAIL: $*"; exit 1; }
[ -f "$DOC" ] || fail "$DOC: missing"
[ -f "$SRC/meson.build" ] || fail "$SRC/meson.build: missing"

modules=$(sed -n "s/^[[:space:]]*subdir('\([A-Za-z0-9_-]*\)').*/\1/p" "$SRC/meson.build" |
	grep -vx tests | sort -u)
[ -n "$modules" ] || fail "$SRC/meson.build: no subdir('...') found"
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT

for m in $modules; do
	[ -d "$SRC/$m" ] || fail "$SRC/meson.build: subdir('$m'), but there is no folder $m/"
done
alt=$(echo $modules | tr ' ' '|')
(cd "$SRC" && find $modules -type f \( -name '*.c' -o -name '*.cpp' -o -name '*.h' \)) |
	sort -u > "$T/tree"
grep -oE "\`($alt)/[A-Za-z0-9_./-]+\.(c|cpp|h)\`" "$DOC" | tr -d '`' | sort -u > "$T/doc" ||
	true

bad=0
for f in $(comm -23 "$T/tree" "$T/doc"); do
	echo "docs/architecture.md: $f is not named (add a line under its module's files)"
	bad=1
done
for f in $(comm -13 "$T/tree" "$T/doc"); do
	echo "docs/architecture.md: names $f, which is not a file of the tree"
	bad=1
done
echo "$modules" > "$T/modules"
grep -oE "^($alt)/ " "$DOC" | tr -d '/ ' | sort -u > "$T/listed" || true
for m in $(comm -23 "$T/modules" "$T/listed"); do
	echo "docs/architecture.md: the folder list has no line for $m/"
	bad=1
done
[ "$bad" = 0 ] || fail "docs/architecture.md is not true to the tree"
echo "docs/architecture.md: $(wc -l < "$T/tree") files of $(echo $modules | wc -w) modules named"
