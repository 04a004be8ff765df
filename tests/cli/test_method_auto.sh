#!/bin/sh
# --method auto takes the method with the lowest mean leave-one-out CIEDE2000 (D65);
# of the methods within 1 % of it, the first in the order pca, linear, wiener,
# rootpoly2, rootpoly3 (the simplest). Checked on the table calib reference prints, on
# the CIE test colours (colord-data) through the demo's two cameras; at least one of
# these charts must rank the methods differently by spectral RMSE, so that the rule
# is really tested (the old rule, lowest RMSE, fails there).
# usage: test_method_auto.sh KOGEI SOURCE_ROOT
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
SRC=$2
kg_need_tcs
kg_temp
D=$SRC/fixtures/demo
differ=0
# camera illuminant gain-amplitude (a per-patch gain 1 + a sin(2.3 k): uneven light)
for c in "reference_camera D65 0" "site_camera A 0" "site_camera D65 0.06" "reference_camera A 0.03"; do
	set -- $c
	"$KOGEI" sim patches --spectra "$TCS" --camera "$D/$1.csv" --illuminant "$2" \
		--noise 50000:3:16 --seed 1 -o "$T/p.cgats" 2>"$T/err" || { cat "$T/err"; fail=1; continue; }
	awk -v amp="$3" '/^BEGIN_DATA[ \t\r]*$/ { d = 1; print; next } /^END_DATA/ { d = 0 }
	     d { k++; g = 1 + amp * sin(k * 2.3); for (i = 2; i <= 4; i++) $i = sprintf("%.6f", $i * g) }
	     { print }' "$T/p.cgats" > "$T/q.cgats"
	if ! "$KOGEI" calib reference --spectra "$TCS" --rgb "$T/q.cgats" --method auto \
		-o "$T/r.json" > "$T/out" 2>"$T/err"; then
		cat "$T/err"; fail=1; continue
	fi
	# chosen, the rule's choice, the lowest-RMSE choice (same 1 % tie rule)
	set -- $(awk '$2 ~ /^[0-9.]+$/ && /^(pca|linear|wiener|rootpoly2|rootpoly3) / {
		n++; name[n] = $1; rm[n] = $3; de[n] = $4; if ($0 ~ /<- default/) ch = $1 }
		END { mr = 1e9; md = 1e9
		      for (i = 1; i <= n; i++) { if (rm[i] < mr) mr = rm[i]; if (de[i] < md) md = de[i] }
		      for (i = 1; i <= n; i++) if (de[i] <= md * 1.01 + 1e-6) { bd = name[i]; dd = de[i]; break }
		      for (i = 1; i <= n; i++) if (rm[i] <= mr * 1.01 + 1e-6) { br = name[i]; dr = de[i]; break }
		      print ch, bd, dd, br, dr, n }' "$T/out")
	echo "$c: auto chose $1; lowest LOO dE00: $2 ($3); lowest LOO RMSE: $4 (dE00 $5); $6 methods"
	check "$c: the table lists the methods" test "${6:-0}" -ge 3
	check "$c: auto takes the lowest leave-one-out dE00 ($2), not $1" test "$1" = "$2"
	check "$c: the file records the choice" grep -q '"leave-one-out"' "$T/r.json"
	[ "$2" != "$4" ] && differ=$((differ + 1))
done
check "at least one chart ranks the methods differently by RMSE and by dE00" test "$differ" -ge 1
"$KOGEI" calib reference --help > "$T/help" 2>&1
check "calib reference --help states the rule" grep -q "leave-one-out dE00 (CIEDE2000 under D65" "$T/help"
exit $fail
