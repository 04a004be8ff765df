/* `kogei acquire` on the sim camera:
 * - bad options exit 2 naming the option; --help exits 0;
 * - a stalling camera (stall=N) and a dropping one (drop=N) exit 3 with the counts,
 *   leave session.json and frames/index.jsonl byte-identical and no output or frames
 *   folder; with --max-dropped the
 *   dropped count in the manifest is the one the drop rule implies;
 * - dark and flat end to end: scenes with a dark offset and vignetting; the corrected
 *   object must be proportional to the scene, equal (to float rounding) to the
 *   uncorrected mean of the same frames (a second session, same sim seed) minus the dark
 *   over the normalised flat (low-passed, kg_flat_smooth), and the manifest must name
 *   the dark and flat used; a dark of another exposure is refused (exit 1) without
 *   touching the session;
 * - a clipped flat and a too uneven one are refused when applied, naming them and the
 *   measured value. */
#include "acq_test.h"
#include "kg_acquire.h"

#define W 96
#define H 64

static int contains(const char *hay, const char *needle) { return strstr(hay, needle) != NULL; }

static void bad_options(void)
{
	char s[4200];
	snprintf(s, sizeof(s), "%s", kg_test_path("bad"));
	static const struct {
		const char *a, *b, *needle;
	} cases[] = {
		{"--frames", "0", "--frames"},       {"--roi", "10x10", "--roi"},
		{"--kind", "photo", "--kind"},       {"--format", "mono9", "--format"},
		{"--bogus", NULL, "--bogus"},        {"--target", "0.5", "--target"},
		{"--exposure", "fast", "--exposure"}, {"--max-dropped", "-1", "--max-dropped"},
		{"--timeout-ms", "0", "--timeout-ms"},
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		int rc = acq_run("acquire", "--camera", "sim:", "--out", s, "--kind",
		                 strcmp(cases[i].a, "--kind") ? "chart" : cases[i].b, cases[i].a,
		                 cases[i].b, NULL);
		CHECK(rc == 2, "%s %s: exit %d, expected 2", cases[i].a, cases[i].b ? cases[i].b : "",
		      rc);
		CHECK(contains(acq_errtext, cases[i].needle), "%s: the message does not name it: %s",
		      cases[i].a, acq_errtext);
	}
	/* --layout names the chart of a chart capture (or the helper's); not an object's */
	int rc = acq_run("acquire", "--camera", "sim:", "--out", s, "--kind", "object", "--layout",
	                 "x.json", NULL);
	CHECK(rc == 2 && contains(acq_errtext, "--layout"), "--layout with an object: exit %d: %s",
	      rc, acq_errtext);
	rc = acq_run("acquire", "--camera", "sim:", "--kind", "chart", NULL);
	CHECK(rc == 2 && contains(acq_errtext, "--out"), "missing --out: exit %d: %s", rc,
	      acq_errtext);
	rc = acq_run("acquire", "--out", s, "--kind", "dark", "--camera", "sim:", "--dark",
	             "dark-0001", NULL);
	CHECK(rc == 2 && contains(acq_errtext, "--dark"), "--dark on a dark: exit %d: %s", rc,
	      acq_errtext);
	CHECK(!kg_test_file_exists(s), "bad options must not create the session");
	rc = acq_run("acquire", "--help", NULL);
	CHECK(rc == 0 && contains(acq_out, "--max-dropped"), "--help: exit %d", rc);
}

/* The camera fails: exit 3, the counts, and the session as it was. */
static void failing_camera(void)
{
	char s[4200];
	snprintf(s, sizeof(s), "%s", kg_test_path("fail"));
	int rc = acq_run("acquire", "--camera", "sim:?width=32&height=24", "--out", s, "--kind",
	                 "object", "--frames", "3", NULL);
	CHECK(rc == 0, "first capture: exit %d: %s", rc, acq_errtext);
	char manifest[8192], outdir[8192];
	snprintf(manifest, sizeof(manifest), "%s/session.json", s);
	static char full_before[1 << 16], full_after[1 << 16];
	static char index_before[1 << 16], index_after[1 << 16];
	char index[8192], framedir[8192];
	snprintf(index, sizeof(index), "%s/frames/index.jsonl", s);
	snprintf(framedir, sizeof(framedir), "%s/frames/object-0002", s);
	acq_slurp(manifest, full_before, sizeof(full_before));
	acq_slurp(index, index_before, sizeof(index_before));
	CHECK(strstr(index_before, "object-0001"), "the first capture's frames are not indexed");

	rc = acq_run("acquire", "--camera", "sim:?width=32&height=24&stall=3", "--out", s,
	             "--kind", "object", "--frames", "6", "--timeout-ms", "200", NULL);
	CHECK(rc == 3, "stall: exit %d, expected 3", rc);
	CHECK(contains(acq_errtext, "3 completed") && contains(acq_errtext, "1 timeouts"),
	      "stall: the counts are missing: %s", acq_errtext);
	acq_slurp(manifest, full_after, sizeof(full_after));
	CHECK(!strcmp(full_before, full_after), "stall: session.json changed");
	snprintf(outdir, sizeof(outdir), "%s/captures/object-0002", s);
	CHECK(!kg_test_file_exists(outdir), "stall: %s exists", outdir);
	/* its raw frames are taken back out too: replay serves only what a manifest lists */
	acq_slurp(index, index_after, sizeof(index_after));
	CHECK(!strcmp(index_before, index_after), "stall: frames/index.jsonl changed");
	CHECK(!kg_test_file_exists(framedir), "stall: %s exists", framedir);

	rc = acq_run("acquire", "--camera", "sim:?width=32&height=24&drop=2", "--out", s,
	             "--kind", "object", "--frames", "6", NULL);
	CHECK(rc == 3, "drop: exit %d, expected 3", rc);
	CHECK(contains(acq_errtext, "1 dropped") && contains(acq_errtext, "--max-dropped"),
	      "drop: the counts are missing: %s", acq_errtext);
	acq_slurp(manifest, full_after, sizeof(full_after));
	CHECK(!strcmp(full_before, full_after), "drop: session.json changed");
	acq_slurp(index, index_after, sizeof(index_after));
	CHECK(!strcmp(index_before, index_after), "drop: frames/index.jsonl changed");
	CHECK(!kg_test_file_exists(framedir), "drop: %s exists", framedir);
	CHECK(acq_check_session(s, NULL, 0) == 1, "the session lost its capture");

	/* Tolerated drops: frames numbered by multiples of 2 are lost, so 6 delivered frames
	 * are 1, 3, ..., 11 and the gaps between them hold 11 - 6 = 5 frames. */
	rc = acq_run("acquire", "--camera", "sim:?width=32&height=24&drop=2", "--out", s,
	             "--kind", "object", "--frames", "6", "--max-dropped", "100", "--name",
	             "dropped-ok", NULL);
	CHECK(rc == 0, "--max-dropped: exit %d: %s", rc, acq_errtext);
	json_t *root = acq_manifest(s);
	json_t *cap = json_array_get(json_object_get(root, "captures"), 1);
	json_t *stream = json_object_get(json_object_get(cap, "statistics"), "stream");
	long long dropped = (long long)json_integer_value(json_object_get(stream, "dropped"));
	CHECK(dropped == 5, "dropped %lld, expected 5", dropped);
	CHECK(json_array_size(json_object_get(cap, "frames")) == 6, "frames listed: %zu",
	      json_array_size(json_object_get(cap, "frames")));
	json_decref(root);
}

static void write_scene(const char *name, double offset, double gain_w, int object)
{
	kg_image *img;
	kg_err err = {{0}};
	kg_image_new(W, H, 1, &img, &err);
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			double dx = (x - W / 2.0) / W, dy = (y - H / 2.0) / H;
			double v = 1 - 1.2 * (dx * dx + dy * dy); /* 0.6 .. 1 */
			double s = object ? 0.2 + 0.6 * ((x / 8 + y / 8) % 4) / 3.0 : gain_w;
			img->data[y * W + x] = (float)(offset + s * v);
		}
	if (kg_image_write_tiff(img, kg_test_path(name), 32, &err))
		fprintf(stderr, "%s\n", err.msg);
	kg_image_free(&img);
}

static double scene_at(int x, int y) { return 0.2 + 0.6 * ((x / 8 + y / 8) % 4) / 3.0; }

static kg_image *read_output(const char *session, const char *capture)
{
	char p[8192];
	snprintf(p, sizeof(p), "%s/captures/%s/mean.tif", session, capture);
	kg_image *img = NULL;
	kg_err err = {{0}};
	if (kg_image_read(p, &img, &err))
		fprintf(stderr, "%s\n", err.msg);
	return img;
}

static void dark_and_flat(void)
{
	const double offset = 0.05;
	write_scene("dark.tif", offset, 0, 0);
	write_scene("flat.tif", offset, 0.7, 0);
	write_scene("object.tif", offset, 0, 1);
	const char *keys = "?format=mono16&bits=16&fullwell=200000&read=3&seed=9";
	char dark_uri[4400], flat_uri[4400], obj_uri[4400];
	snprintf(dark_uri, sizeof(dark_uri), "sim:%s%s", kg_test_path("dark.tif"), keys);
	snprintf(flat_uri, sizeof(flat_uri), "sim:%s%s", kg_test_path("flat.tif"), keys);
	snprintf(obj_uri, sizeof(obj_uri), "sim:%s%s", kg_test_path("object.tif"), keys);
	char a[4200], b[4200];
	snprintf(a, sizeof(a), "%s", kg_test_path("corrected"));
	snprintf(b, sizeof(b), "%s", kg_test_path("plain"));
	int rc = acq_run("acquire", "--camera", dark_uri, "--out", a, "--kind", "dark", "--frames",
	                 "8", "--exposure", "10000", NULL);
	CHECK(rc == 0, "dark: exit %d: %s", rc, acq_errtext);
	rc = acq_run("acquire", "--camera", flat_uri, "--out", a, "--kind", "flat", "--frames", "8",
	             "--exposure", "10000", NULL);
	CHECK(rc == 0, "flat: exit %d: %s", rc, acq_errtext);
	rc = acq_run("acquire", "--camera", obj_uri, "--out", a, "--kind", "object", "--frames",
	             "8", "--exposure", "10000", "--flat", "flat-0001", NULL);
	CHECK(rc == 0, "object: exit %d: %s", rc, acq_errtext);
	rc = acq_run("acquire", "--camera", obj_uri, "--out", b, "--kind", "object", "--frames",
	             "8", "--exposure", "10000", "--dark", "none", NULL);
	CHECK(rc == 0, "uncorrected object: exit %d: %s", rc, acq_errtext);
	CHECK(acq_check_session(a, NULL, 0) == 3, "session with 3 captures");

	json_t *root = acq_manifest(a);
	json_t *caps = json_object_get(root, "captures");
	const char *fd = json_string_value(json_object_get(
		json_object_get(json_array_get(caps, 1), "corrections"), "dark"));
	const char *od = json_string_value(json_object_get(
		json_object_get(json_array_get(caps, 2), "corrections"), "dark"));
	const char *of = json_string_value(json_object_get(
		json_object_get(json_array_get(caps, 2), "corrections"), "flat"));
	CHECK(fd && !strcmp(fd, "dark-0001"), "the flat's dark: %s", fd ? fd : "null");
	CHECK(od && !strcmp(od, "dark-0001") && of && !strcmp(of, "flat-0001"),
	      "the object's dark/flat: %s/%s", od ? od : "null", of ? of : "null");
	json_decref(root);

	kg_image *C = read_output(a, "object-0001"), *U = read_output(b, "object-0001");
	kg_image *D = read_output(a, "dark-0001"), *F = read_output(a, "flat-0001");
	if (!C || !U || !D || !F) {
		CHECK(0, "outputs missing");
		goto out;
	}
	/* exact: C = (U - D) / (smoothed F / mean F), the flat low-passed (kg_flat_smooth) */
	double fm = 0;
	for (int i = 0; i < W * H; i++)
		fm += F->data[i];
	fm /= W * H;
	kg_flat_smooth sm;
	kg_err serr = {{0}};
	CHECK(kg_flat_smooth_init(&sm, W, H, 1, NULL, 0, 0, &serr) == 0, "smooth: %s", serr.msg);
	kg_flat_smooth_add(&sm, F->data, 0, H);
	kg_flat_smooth_finish(&sm);
	double worst = 0, rmin = INFINITY, rmax = 0;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			int i = y * W + x;
			double want = ((double)U->data[i] - D->data[i]) / (kg_flat_smooth_at(&sm, 0, x, y) / fm);
			worst = fmax(worst, fabs(C->data[i] - want) / fabs(want));
			double r = C->data[i] / scene_at(x, y);
			rmin = fmin(rmin, r);
			rmax = fmax(rmax, r);
		}
	kg_flat_smooth_free(&sm);
	CHECK(worst < 1e-5, "corrected object differs from (U - D) / smoothed flat by %.3g", worst);
	/* statistical: the vignetting (40 %) and the offset are gone */
	CHECK(rmax / rmin < 1.03, "corrected / scene spans %.4f .. %.4f", rmin, rmax);
	printf("dark+flat end to end: exact within %.2g; corrected/scene %.4f .. %.4f\n", worst,
	       rmin, rmax);

	/* a dark of another exposure is refused, the session untouched */
	static char m1[1 << 16], m2[1 << 16];
	char mp[8192];
	snprintf(mp, sizeof(mp), "%s/session.json", a);
	acq_slurp(mp, m1, sizeof(m1));
	rc = acq_run("acquire", "--camera", obj_uri, "--out", a, "--kind", "object", "--frames",
	             "2", "--exposure", "5000", "--dark", "dark-0001", NULL);
	CHECK(rc == 1 && contains(acq_errtext, "exposure"), "mismatching dark: exit %d: %s", rc,
	      acq_errtext);
	acq_slurp(mp, m2, sizeof(m2));
	CHECK(!strcmp(m1, m2), "a refused capture changed session.json");

	/* flats by default: the newest of this camera and format; a named older one warns */
	rc = acq_run("acquire", "--camera", flat_uri, "--out", a, "--kind", "flat", "--frames", "2",
	             "--exposure", "10000", NULL);
	CHECK(rc == 0, "second flat: exit %d: %s", rc, acq_errtext);
	rc = acq_run("acquire", "--camera", obj_uri, "--out", a, "--kind", "object", "--frames",
	             "2", "--exposure", "10000", "--name", "by-default", NULL);
	CHECK(rc == 0 && contains(acq_errtext, "flat flat-0002 applied (the session's newest"),
	      "no --flat: the newest flat, said: exit %d: %s", rc, acq_errtext);
	rc = acq_run("acquire", "--camera", obj_uri, "--out", a, "--kind", "object", "--frames",
	             "2", "--exposure", "10000", "--flat", "flat-0001", "--name", "named-old", NULL);
	CHECK(rc == 0 && contains(acq_errtext, "kogei: warning: --flat flat-0001 is older than the "
	                                       "session's newest flat of this camera and format, "
	                                       "flat-0002"),
	      "an older flat named: a warning: exit %d: %s", rc, acq_errtext);
	rc = acq_run("acquire", "--camera", obj_uri, "--out", a, "--kind", "object", "--frames",
	             "2", "--exposure", "10000", "--flat", "none", "--name", "no-flat", NULL);
	CHECK(rc == 0, "--flat none: exit %d: %s", rc, acq_errtext);
	root = acq_manifest(a);
	static const char *const want[][2] = {
		{"by-default", "flat-0002"}, {"named-old", "flat-0001"}, {"no-flat", NULL}};
	for (int k = 0; k < 3; k++) {
		const json_t *cap = NULL, *e;
		size_t i;
		json_array_foreach(json_object_get(root, "captures"), i, e)
			if (!strcmp(json_string_value(json_object_get(e, "name")), want[k][0]))
				cap = e;
		const char *got = json_string_value(kg_json_find(cap, "corrections.flat"));
		CHECK(cap && (want[k][1] ? got && !strcmp(got, want[k][1]) : !got),
		      "%s: corrections.flat %s, expected %s", want[k][0], got ? got : "null",
		      want[k][1] ? want[k][1] : "null");
	}
	json_decref(root);
out:
	kg_image_free(&C);
	kg_image_free(&U);
	kg_image_free(&D);
	kg_image_free(&F);
}

/* A Bayer capture: progress on the terminal frame by frame, and the demosaicing (OpenCV's
 * algorithm, or a note that the build has none) recorded in the manifest beside an
 * rgb.tif that exists only when it was demosaiced. */
static void bayer_capture(void)
{
	char s[4200];
	snprintf(s, sizeof(s), "%s", kg_test_path("bayer"));
	int rc = acq_run("acquire", "--camera", "sim:?width=32&height=24&format=bayer_rggb12",
	                 "--out", s, "--kind", "object", "--frames", "3", "--name", "mosaic", NULL);
	CHECK(rc == 0, "bayer capture: exit %d: %s", rc, acq_errtext);
	for (int i = 1; i <= 3; i++) {
		char want[64];
		snprintf(want, sizeof(want), "mosaic: frame %d/3", i);
		CHECK(contains(acq_errtext, want), "no progress line '%s' in: %s", want, acq_errtext);
	}
	json_t *root = acq_manifest(s);
	json_t *cap = json_array_get(json_object_get(root, "captures"), 0);
	json_t *dm = json_object_get(cap, "demosaic");
	const char *algo = json_string_value(json_object_get(dm, "algorithm"));
	const json_t *rgb = json_object_get(json_object_get(cap, "outputs"), "rgb");
	if (kg_demosaic_algorithm()) {
		CHECK(algo && contains(algo, "OpenCV") && !strcmp(algo, kg_demosaic_algorithm()),
		      "manifest demosaic.algorithm '%s', expected '%s'", algo ? algo : "(none)",
		      kg_demosaic_algorithm());
		CHECK(rgb && json_integer_value(json_object_get(rgb, "channels")) == 3,
		      "no 3-channel rgb output in the manifest");
	} else {
		const char *why = json_string_value(json_object_get(dm, "note"));
		CHECK(dm && json_is_null(json_object_get(dm, "algorithm")) && why &&
		          contains(why, "without OpenCV"),
		      "without OpenCV the manifest must say the mosaic was not demosaiced");
		CHECK(!rgb, "an rgb output without demosaicing");
	}
	json_decref(root);
}

/* A session's folder may hold files kogei did not write (the spectra measured into it,
 * as an older raw workflow did): later captures go on, with a note naming them, and the
 * manifest does not list them. A folder without session.json that holds a file is not a
 * session, and the message says so. */
static void foreign_files(void)
{
	char s[4200], f[4300], other[4200];
	snprintf(s, sizeof(s), "%s", kg_test_path("foreign"));
	int rc = acq_run("acquire", "--camera", "sim:", "--out", s, "--kind", "dark", "--frames",
	                 "1", "--exposure", "1000", NULL);
	CHECK(rc == 0, "first capture: exit %d: %s", rc, acq_errtext);
	snprintf(f, sizeof(f), "%s/chart.cgats", s);
	FILE *fp = fopen(f, "w");
	if (fp) {
		fputs("CGATS.17\n", fp);
		fclose(fp);
	}
	rc = acq_run("acquire", "--camera", "sim:", "--out", s, "--kind", "dark", "--frames", "1",
	             "--exposure", "2000", NULL);
	CHECK(rc == 0, "a capture into a session holding chart.cgats: exit %d: %s", rc,
	      acq_errtext);
	CHECK(contains(acq_errtext, "also holds files kogei did not write (chart.cgats)"),
	      "the note names the file: %s", acq_errtext);
	char manifest[8192];
	snprintf(f, sizeof(f), "%s/session.json", s);
	kg_test_slurp(f, manifest, sizeof(manifest));
	CHECK(!contains(manifest, "chart.cgats"), "the manifest does not list it");
	CHECK(contains(manifest, "\"id\""), "the manifest has the session's id");

	snprintf(other, sizeof(other), "%s", kg_test_path("not-a-session"));
	mkdir(other, 0777);
	snprintf(f, sizeof(f), "%s/IMG_0001.dng", other);
	fp = fopen(f, "w");
	if (fp) {
		fputs("raw", fp);
		fclose(fp);
	}
	rc = acq_run("acquire", "--camera", "sim:", "--out", other, "--kind", "dark", "--frames",
	             "1", NULL);
	CHECK(rc == 1 && contains(acq_errtext, "not a kogei session: it has no session.json and "
	                                       "holds 'IMG_0001.dng'"),
	      "a folder that is not a session: exit %d: %s", rc, acq_errtext);
}

/* Flats that do not measure the light are refused when applied, before any frame,
 * naming the flat and the measured value: one clipped (a uniform target at 1.5 of full
 * scale: every sample at the sensor's top code) and one more uneven than 40 %
 * (a ramp from 0.2 to 0.9 across the frame); taking them says they will be. */
static void flat_refusals(void)
{
	kg_image *img;
	kg_err err = {{0}};
	kg_image_new(W, H, 1, &img, &err);
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++)
			img->data[y * W + x] = (float)(0.2 + 0.7 * x / (W - 1.0));
	if (kg_image_write_tiff(img, kg_test_path("ramp.tif"), 32, &err))
		fprintf(stderr, "%s\n", err.msg);
	kg_image_free(&img);
	const char *keys = "?format=mono16&bits=12&fullwell=20000&read=3&seed=4";
	char clipped[4400], ramp[4400], obj[4400], a[4200];
	snprintf(clipped, sizeof(clipped), "sim:%s%s&uniform=1.5", kg_test_path("ramp.tif"), keys);
	snprintf(ramp, sizeof(ramp), "sim:%s%s", kg_test_path("ramp.tif"), keys);
	snprintf(obj, sizeof(obj), "sim:%s%s&uniform=0.3", kg_test_path("ramp.tif"), keys);
	snprintf(a, sizeof(a), "%s", kg_test_path("bad-flats"));
	int rc = acq_run("acquire", "--camera", clipped, "--out", a, "--kind", "flat", "--frames",
	                 "2", "--exposure", "10000", NULL);
	CHECK(rc == 0 && contains(acq_errtext, "it will be refused as a flat"),
	      "clipped flat: exit %d: %s", rc, acq_errtext);
	rc = acq_run("acquire", "--camera", obj, "--out", a, "--kind", "object", "--frames", "2",
	             "--exposure", "10000", "--flat", "flat-0001", NULL);
	CHECK(rc == 1 && contains(acq_errtext, "flat flat-0001 is clipped: 100 % of its samples "
	                                       "reached the sensor's saturation"),
	      "a clipped flat: exit %d: %s", rc, acq_errtext);
	rc = acq_run("acquire", "--camera", ramp, "--out", a, "--kind", "flat", "--frames", "2",
	             "--exposure", "10000", NULL);
	CHECK(rc == 0 && contains(acq_errtext, "it will be refused as a flat"),
	      "uneven flat: exit %d: %s", rc, acq_errtext);
	rc = acq_run("acquire", "--camera", obj, "--out", a, "--kind", "object", "--frames", "2",
	             "--exposure", "10000", "--flat", "flat-0002", NULL);
	CHECK(rc == 1 && contains(acq_errtext, "flat flat-0002 is too uneven: its dimmest part gets "
	                                       "2"),
	      "an uneven flat: exit %d: %s", rc, acq_errtext);
	printf("refused: %s\n", acq_errtext);
	CHECK(acq_check_session(a, NULL, 0) == 2, "the refused captures were added");
}

int main(int argc, char **argv)
{
	acq_init(argc, argv, "acquire-cli");
	foreign_files();
	bad_options();
	failing_camera();
	bayer_capture();
	dark_and_flat();
	flat_refusals();
	acq_cleanup();
	return kg_test_done("acquire-cli");
}
