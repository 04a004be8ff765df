#!/bin/sh
# Uneven light over a chart, measured from the chart and removed (calib/light_field.c):
# a ColorChecker frame simulated through a real camera (Canon EOS 5D sensitivities)
# under D65 with lens vignetting, detected with the light field on and off. With it
# on, the patch values (against the truth's unvignetted values, one common scale
# removed) and the site calibration's M2 residual (against a Nikon D5100 reference)
# come back close to the evenly lit chart's; off, they are worse and the greys are
# flagged non-uniform. A glare spot is still flagged; an extreme falloff is refused
# with its cause. Reads ../shared/reference (skipped without it).
# usage: test_light_field.sh KOGEI SOURCE_ROOT HAVE_APRILTAG
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
SRC=$2
HAVE_APRILTAG=${3:-1}
kg_need_reference "$SRC" charts/colorchecker24_babelcolor_avg.csv cameras/Nikon_D5100.csv \
	cameras/Canon_EOS_5D.csv
SPECTRA=$REF/charts/colorchecker24_babelcolor_avg.csv
REFCAM=$REF/cameras/Nikon_D5100.csv
SITECAM=$REF/cameras/Canon_EOS_5D.csv
kg_need "$HAVE_APRILTAG" "built without libapriltag"
kg_temp
# awk: is a <= b (numbers)
le() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a + 0 <= b + 0) }'; }
LAYOUT=$SRC/fixtures/charts/colorchecker24-frame.json

# RMS % error of the patches' green values against the truth's unvignetted ones
# after one common scale (the median ratio) is removed.
patch_error() { # patches.cgats truth.cgats
	awk 'function load(file, tab,   d, f, n, i, name) {
		d = 0; f = 0
		while ((getline line < file) > 0) {
			sub(/\r$/, "", line)
			if (line ~ /^BEGIN_DATA_FORMAT/) { f = 1; continue }
			if (line ~ /^END_DATA_FORMAT/) { f = 0; continue }
			if (f) { n = split(line, a, /[ \t]+/); for (i = 1; i <= n; i++) if (a[i] != "") col[file, a[i]] = ++nc[file]; continue }
			if (line ~ /^BEGIN_DATA$/) { d = 1; continue }
			if (line ~ /^END_DATA$/) { d = 0; continue }
			if (d) { n = split(line, a, /[ \t]+/); k = 0; for (i = 1; i <= n; i++) if (a[i] != "") b[++k] = a[i]
				tab[b[1]] = b[col[file, "RGB_G"]] " " (col[file, "FLAT_G"] ? b[col[file, "FLAT_G"]] : "") }
		}
	}
	BEGIN {
		load(ARGV[1], meas); load(ARGV[2], truth); n = 0
		for (id in meas) if (id in truth) {
			split(meas[id], m, " "); split(truth[id], t, " ")
			if (t[2] + 0 > 0) r[++n] = m[1] / t[2]
		}
		# median ratio
		for (i = 1; i <= n; i++) s[i] = r[i]
		for (i = 2; i <= n; i++) { v = s[i]; j = i - 1; while (j > 0 && s[j] > v) { s[j + 1] = s[j]; j-- } s[j + 1] = v }
		med = n % 2 ? s[(n + 1) / 2] : 0.5 * (s[n / 2] + s[n / 2 + 1])
		for (i = 1; i <= n; i++) e += (r[i] / med - 1) ^ 2
		printf "%.3f\n", 100 * sqrt(e / n)
	}' "$1" "$2"
}
# patches flagged non-uniform (FLAGS has 16)
nonuniform() {
	awk '/^BEGIN_DATA_FORMAT/ { f = 1; next } /^END_DATA_FORMAT/ { f = 0; next }
	f { for (i = 1; i <= NF; i++) if ($i == "FLAGS") fc = ++k; else ++k; next }
	/^BEGIN_DATA$/ { d = 1; next } /^END_DATA$/ { d = 0 }
	d && int($fc / 16) % 2 == 1 { n++ } END { print n + 0 }' "$1"
}
# the M2 residual in %, from calib camera's report ("... RMS x, relative 0.0113")
residual() { sed -n 's/^residual rho0.*relative \([0-9.]*\).*/\1/p' "$T/out" | awk '{ printf "%.3f", 100 * $1 }'; }

# The reference: the Nikon D5100 under D65 on the 24 spectra.
expect_exit 0 "$KOGEI" sim patches --spectra "$SPECTRA" --camera "$REFCAM" \
	--illuminant D65 --noise 50000:3:16 -o "$T/ref_rgb.cgats"
expect_exit 0 "$KOGEI" calib reference --spectra "$SPECTRA" --rgb "$T/ref_rgb.cgats" -o "$T/ref.json"

sim() { # name vignetting [more options]
	name=$1; vig=$2; shift 2
	expect_exit 0 "$KOGEI" sim chart --layout "$LAYOUT" --spectra "$SPECTRA" --camera "$SITECAM" \
		--illuminant D65 --tilt 15 --rotate 4 --fill 0.95 --width 900 --height 660 \
		--vignetting "$vig" --noise 20000:5:12 --depth 16 --seed 3 "$@" \
		-o "$T/$name.tif" --truth "$T/$name.truth.cgats"
}
detect() { # name on|off
	expect_exit 0 "$KOGEI" chart detect --layout "$LAYOUT" "$T/$1.tif" --light-field "$2" \
		-o "$T/$1.$2.cgats"
	# the reference's ids are the spectra's, 1..24 in reading order
	awk '/^BEGIN_DATA$/ { d = 1; print; next } /^END_DATA$/ { d = 0 }
	d { $1 = (index("ABCD", substr($1, 1, 1)) - 1) * 6 + substr($1, 2) } { print }' \
		"$T/$1.$2.cgats" > "$T/$1.$2.ids.cgats"
	expect_exit 0 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/$1.$2.ids.cgats" \
		--max-residual 5 -o "$T/$1.$2.json"
	res=$(residual)
	# the chart's own leave-one-out error: a reference fitted on these patch values
	# (the default method's LOO dE00 under D65)
	expect_exit 0 "$KOGEI" calib reference --spectra "$SPECTRA" --rgb "$T/$1.$2.ids.cgats" \
		-o "$T/$1.$2.ref.json"
	loo=$(awk '/<- default/ { print $4 }' "$T/out")
}

sim even 0
sim vignetted 0.6
for n in even vignetted; do
	for m in on off; do
		detect $n $m
		eval "res_${n}_$m=\$res"
		eval "loo_${n}_$m=\$loo"
		eval "err_${n}_$m=\$(patch_error '$T/$n.$m.cgats' '$T/$n.truth.cgats')"
		eval "nu_${n}_$m=\$(nonuniform '$T/$n.$m.cgats')"
	done
done
echo "even light:        patch error on $err_even_on % off $err_even_off %, M2 residual on $res_even_on % off $res_even_off %, LOO dE00 on $loo_even_on off $loo_even_off, non-uniform on $nu_even_on off $nu_even_off"
echo "vignetting 0.6:    patch error on $err_vignetted_on % off $err_vignetted_off %, M2 residual on $res_vignetted_on % off $res_vignetted_off %, LOO dE00 on $loo_vignetted_on off $loo_vignetted_off, non-uniform on $nu_vignetted_on off $nu_vignetted_off"
grep "^LIGHT_FIELD" "$T/vignetted.on.cgats"
check "the field's variation is in the patch file" grep -q '^LIGHT_FIELD_VARIATION_PERCENT "[0-9.]*"' "$T/vignetted.on.cgats"
check "off is recorded" grep -q '^LIGHT_FIELD "off"' "$T/vignetted.off.cgats"
var=$(sed -n 's/^LIGHT_FIELD_VARIATION_PERCENT "\([0-9.]*\)"/\1/p' "$T/vignetted.on.cgats")
check "vignetting 0.6: the field varies by more than 10 % ($var)" le 10 "$var"
# vignetting costs without the field ...
check "uncorrected patch error $err_vignetted_off % > 3 x corrected $err_vignetted_on %" \
	le "$(awk -v a="$err_vignetted_on" 'BEGIN { print 3 * a }')" "$err_vignetted_off"
check "uncorrected M2 residual $res_vignetted_off % > 1.5 x corrected $res_vignetted_on %" \
	le "$(awk -v a="$res_vignetted_on" 'BEGIN { print 1.5 * a }')" "$res_vignetted_off"
# ... and with it, close to the even light's
check "corrected patch error $err_vignetted_on % <= 1.5 x even light's $err_even_on % + 0.2" \
	le "$err_vignetted_on" "$(awk -v a="$err_even_on" 'BEGIN { print 1.5 * a + 0.2 }')"
check "corrected M2 residual $res_vignetted_on % <= 1.2 x even light's $res_even_on % + 0.2" \
	le "$res_vignetted_on" "$(awk -v a="$res_even_on" 'BEGIN { print 1.2 * a + 0.2 }')"
check "uncorrected LOO dE00 $loo_vignetted_off > 1.5 x corrected $loo_vignetted_on" \
	le "$(awk -v a="$loo_vignetted_on" 'BEGIN { print 1.5 * a }')" "$loo_vignetted_off"
check "corrected LOO dE00 $loo_vignetted_on <= 1.1 x even light's $loo_even_on + 0.1" \
	le "$loo_vignetted_on" "$(awk -v a="$loo_even_on" 'BEGIN { print 1.1 * a + 0.1 }')"
check "even light: the field changes little ($err_even_on vs $err_even_off)" \
	le "$err_even_on" "$(awk -v a="$err_even_off" 'BEGIN { print a + 0.2 }')"
# the greys are not dropped as non-uniform once the light is removed
check "vignetting 0.6 off: patches flagged non-uniform ($nu_vignetted_off)" le 4 "$nu_vignetted_off"
check "vignetting 0.6 on: none flagged non-uniform ($nu_vignetted_on)" le "$nu_vignetted_on" 0

# Glare over the middle patch under the same vignetting: still flagged.
sim glare 0.6 --glare
expect_exit 0 "$KOGEI" chart detect --layout "$LAYOUT" "$T/glare.tif" -o "$T/glare.cgats"
glared=$(awk '$NF != "" && /^BEGIN_DATA$/ { d = 1; next } /^END_DATA$/ { d = 0 } d && $NF % 4 >= 2 || d && int($NF / 16) % 2 { n++ } END { print n + 0 }' "$T/glare.cgats")
awk '/^BEGIN_DATA$/ { d = 1; next } /^END_DATA$/ { d = 0 } d && $NF != 0' "$T/glare.cgats"
check "glare: flagged (glare or non-uniform) on $glared patches" le 1 "$glared"
check "glare: the truth puts glare there" awk '/^BEGIN_DATA$/ { d = 1; next } /^END_DATA$/ { d = 0 } d && $NF == 1 { f = 1 } END { exit !f }' "$T/glare.truth.cgats"

# An extreme falloff: refused with the cause, no patch file.
sim extreme 0.93
expect_exit 1 "$KOGEI" chart detect --layout "$LAYOUT" "$T/extreme.tif" -o "$T/extreme.cgats"
cat "$T/err"
check "extreme: the cause" grep -q "the light across chart colorchecker24-frame varies by" "$T/err"
check "extreme: the image named" grep -q "extreme.tif" "$T/err"
check "extreme: no patch file" test ! -e "$T/extreme.cgats"
# a larger limit lets it through
expect_exit 0 "$KOGEI" chart detect --layout "$LAYOUT" "$T/extreme.tif" --max-light-variation 5 \
	-o "$T/extreme.cgats"

[ $fail = 0 ] && echo "light-field-cli: ok"
exit $fail
