#!/bin/sh
# Hostile names through the real CLI, every written file parsed back by a real parser
# (hostile_names.py says what is checked): xmllint (libxml2-utils) for the Mitsuba
# XML, Python's json and html.parser, kogei's own CGATS and ENVI readers (read_names).
# usage: test_hostile_names.sh KOGEI READ_NAMES MAKE_REPORT_FIXTURE SOURCE_ROOT HAVE_EMBREE
set -u
. "$(dirname "$0")/../lib.sh"
command -v xmllint >/dev/null 2>&1 ||
	kg_skip "xmllint not found (package libxml2-utils): the XML written is parsed with it"
kg_python json
kg_temp
abs() { case $1 in /*) echo "$1" ;; *) echo "$(pwd)/$1" ;; esac; }
"$PY" "$(dirname "$0")/hostile_names.py" "$(abs "$1")" "$(abs "$2")" "$(abs "$3")" \
	"$(abs "$4")" "${5:-0}" "$T"
