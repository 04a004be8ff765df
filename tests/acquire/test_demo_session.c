/* The bundled demo session (fixtures/demo/session) replays: each capture is acquired
 * again from replay:SESSION#CAPTURE with the settings its manifest records; the mean
 * must equal the average of the bundled raw frames computed here from the bytes
 * (frames/index.jsonl, 16-bit little-endian words) to float rounding, and the charts
 * must be found (AprilTag) with every patch within 0.5 % of full scale of the
 * noise-free truth `kogei sim chart` wrote beside the session. */
#include "acq_test.h"
#include "kg_calib.h"

static void read_index(const char *bundle, const char *capture, char files[][128], int *n)
{
	char path[4400], line[4096];
	snprintf(path, sizeof(path), "%s/frames/index.jsonl", bundle);
	FILE *f = fopen(path, "r");
	*n = 0;
	while (f && fgets(line, sizeof(line), f) && *n < 16) {
		json_t *o = json_loads(line, 0, NULL);
		const char *c = json_string_value(json_object_get(o, "capture"));
		if (c && !strcmp(c, capture))
			snprintf(files[(*n)++], 128, "%s", json_string_value(json_object_get(o, "file")));
		json_decref(o);
	}
	if (f)
		fclose(f);
}

/* The mean of the raw frames against mean.tif. */
static void check_mean(const char *bundle, const char *capture, int bits, const char *mean_tif)
{
	char files[16][128];
	int n;
	read_index(bundle, capture, files, &n);
	kg_image *img = NULL;
	kg_err err = {{0}};
	CHECK(n > 0 && kg_image_read(mean_tif, &img, &err) == 0, "%s: %d frames; %s", capture, n,
	      err.msg);
	if (!img)
		return;
	size_t ns = (size_t)img->width * (size_t)img->height * (size_t)img->channels;
	long double *sum = calloc(ns, sizeof(long double));
	unsigned char *buf = malloc(2 * ns);
	for (int k = 0; k < n; k++) {
		char p[8192];
		snprintf(p, sizeof(p), "%s/%s", bundle, files[k]);
		FILE *f = fopen(p, "rb");
		size_t got = f ? fread(buf, 1, 2 * ns, f) : 0;
		if (f)
			fclose(f);
		CHECK(got == 2 * ns, "%s: %zu bytes, expected %zu", p, got, 2 * ns);
		for (size_t i = 0; i < ns && got == 2 * ns; i++)
			sum[i] += buf[2 * i] | buf[2 * i + 1] << 8;
	}
	double worst = 0;
	for (size_t i = 0; i < ns; i++) {
		double want = (double)(sum[i] / n / ((1u << bits) - 1u));
		worst = fmax(worst, fabs(img->data[i] - want) / (want * 6e-8 + 1e-30));
	}
	CHECK(worst <= 1.05, "%s: mean.tif off the frames' average by %.3g float half-ulps",
	      capture, worst);
	printf("%s: mean of %d bundled frames matches within %.2f half-ulps\n", capture, n, worst);
	free(sum);
	free(buf);
	kg_image_free(&img);
}

static void check_chart(const char *image, const char *truth_path)
{
#if HAVE_APRILTAG
	char layout_path[4400];
	snprintf(layout_path, sizeof(layout_path), "%s/fixtures/demo/cie-tcs-frame.json",
	         KG_SOURCE_ROOT);
	kg_chart_layout *layout = NULL;
	kg_image *img = NULL;
	kg_chart_result *res = NULL;
	kg_patchset *truth = NULL;
	kg_chart_detect_options opt;
	kg_chart_detect_options_default(&opt);
	kg_err err = {{0}};
	int ret = kg_chart_layout_load(layout_path, &layout, &err);
	if (!ret)
		ret = kg_image_read(image, &img, &err);
	if (!ret)
		ret = kg_patchset_read(truth_path, 0, &truth, &err);
	if (!ret)
		ret = kg_chart_detect(layout, img, &opt, &res, &err);
	CHECK(ret == 0, "%s: %s", image, err.msg);
	double worst = 0;
	int found = 0;
	for (int i = 0; !ret && i < res->npatches; i++) {
		int k = kg_patchset_find(truth, res->patches[i].id);
		if (k < 0 || (res->patches[i].flags & KG_CHART_FLAG_REJECTED))
			continue;
		found++;
		/* the truth is the value as imaged, the site chart's vignetting in it: the
		 * detector's value times the light field it removed */
		for (int c = 0; c < 3; c++)
			worst = fmax(worst, fabs(res->patches[i].rgb[c] * res->patches[i].light -
			                         truth->rgb[k][c]));
	}
	CHECK(ret || found == truth->n, "%s: %d of %d patches", image, found, truth ? truth->n : 0);
	CHECK(ret || worst < 0.005, "%s: a patch is %.4f off its truth", image, worst);
	if (!ret)
		printf("%s: %d tags used, %d patches, largest error %.5f of full scale\n", image,
		       res->ntags_used, found, worst);
	kg_chart_result_free(&res);
	kg_patchset_free(&truth);
	kg_image_free(&img);
	kg_chart_layout_free(&layout);
#else
	(void)image;
	(void)truth_path;
	printf("chart detection: built without AprilTag, not tested\n");
#endif
}

int main(int argc, char **argv)
{
	acq_init(argc, argv, "acquire-demo-session");
	char bundle[4200], manifest_path[4400], out[4200];
	snprintf(bundle, sizeof(bundle), "%s/fixtures/demo/session", KG_SOURCE_ROOT);
	snprintf(manifest_path, sizeof(manifest_path), "%s/session.json", bundle);
	snprintf(out, sizeof(out), "%s", kg_test_path("replayed"));
	json_t *root = json_load_file(manifest_path, 0, NULL);
	CHECK(root != NULL, "%s does not parse", manifest_path);
	json_t *cap;
	size_t i;
	int n = 0;
	json_array_foreach(json_object_get(root, "captures"), i, cap)
	{
		const char *name = json_string_value(json_object_get(cap, "name"));
		const char *kind = json_string_value(json_object_get(cap, "kind"));
		json_t *st = json_object_get(cap, "settings"), *fmt = json_object_get(st, "format");
		char uri[4400], frames[16], exposure[32], format[32];
		snprintf(uri, sizeof(uri), "replay:%s#%s", bundle, name);
		snprintf(frames, sizeof(frames), "%lld",
		         (long long)json_integer_value(json_object_get(st, "frames")));
		snprintf(exposure, sizeof(exposure), "%.17g",
		         json_number_value(json_object_get(st, "exposure_us")));
		int bits = (int)json_integer_value(json_object_get(fmt, "bits"));
		snprintf(format, sizeof(format), "%s", json_string_value(json_object_get(fmt, "pixfmt")));
		int rc = acq_run("acquire", "--camera", uri, "--out", out, "--name", name, "--kind",
		                 kind, "--frames", frames, "--exposure", exposure, "--dark", "none",
		                 NULL);
		CHECK(rc == 0, "%s: exit %d: %s", name, rc, acq_errtext);
		if (rc)
			continue;
		n++;
		char mean[4600], rgb[4600], truth[4600];
		snprintf(mean, sizeof(mean), "%s/captures/%s/mean.tif", out, name);
		snprintf(rgb, sizeof(rgb), "%s/captures/%s/rgb.tif", out, name);
		CHECK(!strncmp(format, "bayer16", 7) || !strncmp(format, "rgb16", 5) ||
		          !strncmp(format, "mono16", 6),
		      "%s: bundled as %s, expected 16-bit words", name, format);
		check_mean(bundle, name, bits, mean);
		if (!strcmp(kind, "chart")) {
			snprintf(truth, sizeof(truth), "%s/fixtures/demo/%.*s_chart_truth.cgats",
			         KG_SOURCE_ROOT, (int)(strchr(name, '-') - name), name);
			check_chart(mean, truth); /* the raw mosaic: detection demosaics it */
			if (kg_test_file_exists(rgb))
				check_chart(rgb, truth); /* OpenCV's demosaicing */
		}
		json_t *outputs = json_object_get(cap, "outputs");
		const char *want =
			json_string_value(json_object_get(json_object_get(outputs, "mean"), "sha256"));
		char got[65] = "";
		acq_sha256_file(mean, got);
		printf("%s: mean.tif sha256 %s the recording's\n", name,
		       want && !strcmp(want, got) ? "equals" : "differs from (another kogei wrote it)");
	}
	CHECK(n == 3, "%d captures replayed, expected 3", n);
	json_decref(root);
	acq_cleanup();
	return kg_test_done("acquire-demo-session");
}
