# The set-up the shell tests share; a test sources it first:
#   . "$(dirname "$0")/../lib.sh"
# It sets fail=0 (a test ends with `exit $fail`) and KG_ROOT (the source tree: meson's
# KOGEI_SOURCE_ROOT, or the folder above the test's own tests/ folder), and gives:
#   kg_skip WHY                  print "SKIP: WHY", exit 77 (meson: skipped)
#   kg_need FLAG WHY             skip unless FLAG is 1 (a meson option found)
#   kg_need_file FILE WHAT       skip unless FILE is readable ("FILE missing (WHAT)")
#   kg_need_tcs                  TCS: the CIE test colours of colord-data, or skip
#   kg_need_reference ROOT F...  REF: the reference data beside the source tree ROOT
#                                (or $KOGEI_REFERENCE); skip unless REF/F... are readable
#   kg_python [MODULE]           PY: python3 (/usr/bin first); skip without MODULE
#   kg_temp                      T: a temporary folder, removed on exit (kept with KEEP=1)
#   check DESC COMMAND...        fail unless COMMAND succeeds (KG_CHECK_OK=1: print "ok:")
#   check_eval DESC 'SHELL'      the same for a shell expression, evaluated
#   expect_exit CODE COMMAND...  fail unless COMMAND exits CODE; its output in $T/out,
#                                $T/err (the error shown when the code is wrong)
#   run COMMAND...               fail unless COMMAND exits 0 (output as expect_exit's)
#   run_or_exit COMMAND...       the same, but a failure ends the test (set-up steps)

fail=0
KG_ROOT=${KOGEI_SOURCE_ROOT:-$(cd "$(dirname "$0")/../.." && pwd)}

kg_skip() {
	echo "SKIP: $*"
	exit 77
}

kg_need() { # FLAG WHY
	[ "${1:-1}" = 1 ] || kg_skip "$2"
}

kg_need_file() { # FILE WHAT
	[ -r "$1" ] || kg_skip "$1 missing ($2)"
}

kg_need_tcs() {
	TCS=/usr/share/colord/ref/CIE-TCS.sp
	kg_need_file "$TCS" "package colord-data"
}

kg_need_reference() { # ROOT FILE...: sets REF
	REF=${KOGEI_REFERENCE:-$1/../shared/reference}
	shift
	for f in "$@"; do
		kg_need_file "$REF/$f" "reference data"
	done
}

kg_python() { # [MODULE]: sets PY
	PY=/usr/bin/python3
	[ -x "$PY" ] || PY=python3
	if [ -n "${1:-}" ]; then
		"$PY" -c "import $1" 2>/dev/null || kg_skip "python3 module $1 missing"
	fi
}

kg_temp() { # sets T
	T=$(mktemp -d) || exit 1
	trap '[ -n "${KEEP:-}" ] || rm -rf "$T"' EXIT
}

check() { # description, command...
	desc=$1
	shift
	if "$@"; then
		[ -z "${KG_CHECK_OK:-}" ] || echo "ok: $desc"
	else
		echo "FAIL: $desc"
		fail=1
	fi
}

check_eval() { # description, shell expression
	if ! eval "$2"; then
		echo "FAIL: $1"
		fail=1
	fi
}

expect_exit() { # code, command...
	want=$1
	shift
	"$@" >"$T/out" 2>"$T/err"
	got=$?
	if [ "$got" != "$want" ]; then
		echo "FAIL: '$*' exited $got, expected $want"
		cat "$T/err"
		fail=1
	fi
}

run() { # command...: must exit 0
	expect_exit 0 "$@"
}

run_or_exit() { # command...: must exit 0, or the test ends here
	"$@" >"$T/out" 2>"$T/err" || {
		echo "FAIL: '$*' exited $?"
		cat "$T/err"
		exit 1
	}
}
