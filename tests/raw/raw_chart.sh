# The start the raw tests on the reference ColorChecker share; sourced after tests/lib.sh.
# raw_chart_setup KOGEI SOURCE_ROOT MAKE_DNG HAVE_TAGS_AND_DEMOSAIC HAVE_LIBRAW: skips
# without those features or the reference data; sets KOGEI, SRC, MAKE_DNG, CHART (the
# ColorChecker's spectra, Ohta 1997), CSS (the Canon EOS 5D Mark IV's sensitivities)
# and T, and prints the checks that pass.
raw_chart_setup() {
	KOGEI=$1
	SRC=$2
	MAKE_DNG=$3
	kg_need "${4:-1}" "built without libapriltag or OpenCV"
	kg_need "${5:-1}" "built without LibRaw"
	kg_need_reference "$SRC" charts/colorchecker24_ohta1997.csv \
		cameras/Canon_EOS_5D_Mark_IV.csv
	CHART=$REF/charts/colorchecker24_ohta1997.csv
	CSS=$REF/cameras/Canon_EOS_5D_Mark_IV.csv
	kg_temp
	KG_CHECK_OK=1
}
