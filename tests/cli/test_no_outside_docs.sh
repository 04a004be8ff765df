#!/bin/sh
# No file of the repository sends a reader to the design, notes or style files that
# live outside it: what they say belongs in docs/ (architecture.md, formats.md) or in
# place. Skipped (77) outside a git checkout.
# usage: test_no_outside_docs.sh (KOGEI_SOURCE_ROOT set)
set -u
root=${KOGEI_SOURCE_ROOT:?}
if ! command -v git >/dev/null 2>&1 ||
   ! git -C "$root" rev-parse --is-inside-work-tree >/dev/null 2>&1; then
	echo "SKIP: $root is not a git checkout"
	exit 77
fi
# The names are spelt in two parts so that this file does not match itself.
names='(DESIGN|NOTES|STYLE)'
if git -C "$root" grep -nIE "$names[.]md" -- .; then
	echo "FAIL: the files above refer to files outside the repository; point them at docs/"
	exit 1
fi
echo "no-outside-docs: ok"
