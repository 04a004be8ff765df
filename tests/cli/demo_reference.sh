# The start the calibration tests of tests/cli share; sourced after tests/lib.sh, with
# KOGEI, SRC (the source tree) and T set.
# demo_reference HAVE_APRILTAG: skips without colord-data or libapriltag; sets D (the
# demo's fixtures) and LAYOUT (its CIE test colour chart in an AprilTag frame), and
# calibrates the demo's reference camera under D65 on the CIE test colours: $T/ref.json
# (from $T/ref_rgb.cgats).
demo_reference() {
	kg_need_tcs
	kg_need "$1" "built without libapriltag"
	D=$SRC/fixtures/demo
	LAYOUT=$D/cie-tcs-frame.json
	expect_exit 0 "$KOGEI" sim patches --spectra "$TCS" --camera "$D/reference_camera.csv" \
		--illuminant D65 --noise 50000:3:16 -o "$T/ref_rgb.cgats"
	expect_exit 0 "$KOGEI" calib reference --spectra "$TCS" --rgb "$T/ref_rgb.cgats" \
		-o "$T/ref.json"
}
