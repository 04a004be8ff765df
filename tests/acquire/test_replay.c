/* Record with sim:, acquire again from replay:SESSION#CAPTURE into another session:
 * every output file (mean, variance, demosaiced RGB) must be byte-identical, and so
 * must the raw frames (their sha256 in the two manifests). Covers a Bayer ROI, a dark
 * chosen automatically, and the exposure helper (its metering frames are replayed in
 * order). A replay asked for another exposure fails and leaves the session as it was. */
#include "acq_test.h"

static int same_outputs(const char *a, const char *b, const char *capture)
{
	static const char *const files[] = {"mean.tif", "variance.tif", "rgb.tif"};
	int compared = 0;
	for (int i = 0; i < 3; i++) {
		char pa[4400], pb[4400];
		snprintf(pa, sizeof(pa), "%s/captures/%s/%s", a, capture, files[i]);
		snprintf(pb, sizeof(pb), "%s/captures/%s/%s", b, capture, files[i]);
		if (!kg_test_file_exists(pa)) {
			CHECK(!kg_test_file_exists(pb), "%s exists only in the replay", pb);
			continue;
		}
		CHECK(acq_same_file(pa, pb) == 0, "%s and %s differ", pa, pb);
		compared++;
	}
	return compared;
}

/* The frames' sha256 of a capture, joined. */
static void frame_hashes(const char *session, int i, char *out, size_t len)
{
	json_t *root = acq_manifest(session);
	json_t *cap = json_array_get(json_object_get(root, "captures"), (size_t)i), *f;
	size_t k;
	out[0] = 0;
	json_array_foreach(json_object_get(cap, "frames"), k, f)
	{
		size_t n = strlen(out);
		snprintf(out + n, len - n, "%s ", json_string_value(json_object_get(f, "sha256")));
	}
	json_decref(root);
}

int main(int argc, char **argv)
{
	acq_init(argc, argv, "acquire-replay");
	char a[4200], b[4200];
	snprintf(a, sizeof(a), "%s", kg_test_path("recorded"));
	snprintf(b, sizeof(b), "%s", kg_test_path("replayed"));
	const char *sim = "sim:?width=96&height=72&format=bayer_rggb12&seed=3";
	/* name, kind, exposure, then the same options for record and replay */
	static const char *const caps[][4] = {
		{"dark-0001", "dark", "5000", "4"},
		{"chart-0001", "chart", "5000", "5"},
		{"object-0001", "object", "auto", "3"},
	};
	for (int i = 0; i < 3; i++) {
		int rc = acq_run("acquire", "--camera", sim, "--out", a, "--kind", caps[i][1],
		                 "--exposure", caps[i][2], "--frames", caps[i][3], "--roi",
		                 "64x48+16+8", NULL);
		CHECK(rc == 0, "record %s: exit %d: %s", caps[i][0], rc, acq_errtext);
	}
	char names[3][64];
	CHECK(acq_check_session(a, names, 3) == 3, "recorded session");
	for (int i = 0; i < 3; i++) {
		char uri[4400];
		snprintf(uri, sizeof(uri), "replay:%s#%s", a, caps[i][0]);
		int rc = acq_run("acquire", "--camera", uri, "--out", b, "--kind", caps[i][1],
		                 "--exposure", caps[i][2], "--frames", caps[i][3], "--roi",
		                 "64x48+16+8", NULL);
		CHECK(rc == 0, "replay %s: exit %d: %s", caps[i][0], rc, acq_errtext);
	}
	CHECK(acq_check_session(b, NULL, 0) == 3, "replayed session");
	int files = 0;
	for (int i = 0; i < 3; i++) {
		files += same_outputs(a, b, caps[i][0]);
		static char ha[1 << 14], hb[1 << 14];
		frame_hashes(a, i, ha, sizeof(ha));
		frame_hashes(b, i, hb, sizeof(hb));
		CHECK(ha[0] && !strcmp(ha, hb), "%s: the raw frames differ", caps[i][0]);
	}
	/* mean + variance of 3 captures, rgb of those demosaiced (OpenCV) */
	CHECK(files >= 6, "only %d output files compared", files);
	json_t *root = acq_manifest(b);
	json_t *chart = json_array_get(json_object_get(root, "captures"), 1);
	const char *dark = json_string_value(json_object_get(json_object_get(chart, "corrections"),
	                                                     "dark"));
	CHECK(dark && !strcmp(dark, "dark-0001"), "the replayed chart's dark: %s",
	      dark ? dark : "null");
	json_decref(root);
	printf("record -> replay: %d output files byte-identical\n", files);

	/* a replay cannot re-expose */
	static char m1[1 << 17], m2[1 << 17];
	char mp[4400], uri[4400];
	snprintf(mp, sizeof(mp), "%s/session.json", b);
	snprintf(uri, sizeof(uri), "replay:%s#chart-0001", a);
	acq_slurp(mp, m1, sizeof(m1));
	int rc = acq_run("acquire", "--camera", uri, "--out", b, "--kind", "chart", "--exposure",
	                 "6000", "--frames", "5", "--roi", "64x48+16+8", NULL);
	CHECK(rc != 0 && strstr(acq_errtext, "6000"), "other exposure: exit %d: %s", rc,
	      acq_errtext);
	acq_slurp(mp, m2, sizeof(m2));
	CHECK(!strcmp(m1, m2), "a failed replay changed session.json");
	acq_cleanup();
	return kg_test_done("acquire-replay");
}
