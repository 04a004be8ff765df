# Small sessions for the collection tests, sourced after tests/lib.sh with KOGEI and FIX
# set and T the test's folder: coll_sessions DIR N makes DIR/chart.cgats (the chart
# measured by the simulated spectrophotometer) and the sessions DIR/s1 .. DIR/sN (a
# 400x300 chart capture under CIE A and one object capture, with accession=<name>),
# and coll_broken DIR NAME a session with an object but no chart (kogei process
# refuses it: "no chart capture"); coll_fix DIR NAME adds the chart to it.
COLL_CAM='format=bayer_rggb12&fullwell=20000&read=5&serial=site-1'

coll_scenes() { # DIR
	"$KOGEI" sim chart --layout cie-tcs-frame --spectra /usr/share/colord/ref/CIE-TCS.sp \
		--camera "$FIX/demo/site_camera.csv" --illuminant A --tilt 25 --width 400 \
		--height 300 -o "$1/chart.tif" >/dev/null &&
	"$KOGEI" sim image --materials default --camera "$FIX/demo/site_camera.csv" \
		--illuminant A --angle 30 --patch-size 20 --size 400x300 -o "$1/object.tif" \
		>/dev/null &&
	"$KOGEI" measure --spectro sim:/usr/share/colord/ref/CIE-TCS.sp --chart cie-tcs-frame \
		--yes -o "$1/chart.cgats" >/dev/null 2>&1
}

coll_chart() { # SESSION SCENES
	"$KOGEI" acquire --camera "sim:$2/chart.tif?$COLL_CAM" --out "$1" --kind chart \
		--exposure 10000 --gain 0 --frames 2 --layout cie-tcs-frame >/dev/null 2>&1
}

coll_object() { # SESSION SCENES NAME
	"$KOGEI" acquire --camera "sim:$2/object.tif?$COLL_CAM" --out "$1" --kind object \
		--exposure 10000 --gain 0 --frames 2 --meta "accession=$3" >/dev/null 2>&1
}

coll_sessions() { # DIR N
	mkdir -p "$1/scenes" && coll_scenes "$1/scenes" && cp "$1/scenes/chart.cgats" "$1/" &&
	coll_chart "$1/s1" "$1/scenes" && coll_object "$1/s1" "$1/scenes" s1 || return 1
	i=2
	while [ $i -le "$2" ]; do
		# the same recording under another name: a session of its own (its accession)
		cp -r "$1/s1" "$1/s$i" || return 1
		i=$((i + 1))
	done
}

coll_broken() { # DIR NAME
	coll_object "$1/$2" "$1/scenes" "$2"
}

coll_fix() { # DIR NAME
	coll_chart "$1/$2" "$1/scenes"
}
