/* kg_report_write on a synthetic OUTDIR (report_fixture.h): the page is
 * self-contained, has every section, shows the per-patch numbers and the grades,
 * escapes text from process.json, states missing pieces, and refuses a record with
 * a required key missing (naming the file and the key) without touching the page, and
 * inlines no image whose path leaves OUTDIR (absolute, "..", a symbolic link).
 * argv[1]: the kogei program, for `kogei report` exit statuses. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "kg_pipeline.h"
#include "kg_test.h"
#include "report_fixture.h"

static char *read_text(const char *path)
{
	char *buf = NULL;
	size_t len;
	kg_err err;
	if (kg_read_file(path, &buf, &len, &err)) {
		CHECK(0, "%s", err.msg);
		return NULL;
	}
	return buf;
}

static int contains(const char *page, const char *s)
{
	return strstr(page, s) != NULL;
}

/* Decodes the base64 run at p (up to its closing quote) into a whole PNG: its
 * signature, chunks whose lengths chain to the end, and IEND last. Returns the
 * decoded length, 0 when any of that fails. */
static size_t check_png_payload(const char *p)
{
	static const char digits[] =
		"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
	const char *end = strchr(p, '"');
	if (!end || (end - p) % 4)
		return 0;
	size_t n = 0, cap = (size_t)(end - p) / 4 * 3;
	unsigned char *png = malloc(cap ? cap : 1);
	for (const char *q = p; png && q < end; q += 4) {
		uint32_t v = 0;
		int pad = 0;
		for (int k = 0; k < 4; k++) {
			const char *d = q[k] == '=' ? NULL : strchr(digits, q[k]);
			if (q[k] == '=')
				pad++;
			else if (!d || !q[k] || pad) {
				free(png);
				return 0;
			}
			v = v << 6 | (d ? (uint32_t)(d - digits) : 0);
		}
		for (int k = 0; k < 3 - pad; k++)
			png[n++] = (unsigned char)(v >> (16 - 8 * k));
	}
	static const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
	size_t at = 8;
	int ok = png && n > 8 && memcmp(png, sig, 8) == 0, iend = 0;
	while (ok && !iend && at + 12 <= n) {
		size_t len = (size_t)png[at] << 24 | (size_t)png[at + 1] << 16 |
		             (size_t)png[at + 2] << 8 | png[at + 3];
		iend = memcmp(png + at + 4, "IEND", 4) == 0;
		at += 12 + len;
	}
	ok = ok && iend && at == n;
	free(png);
	return ok ? n : 0;
}

static void check_self_contained(const char *page)
{
	CHECK(!strcasestr(page, "http://") && !strcasestr(page, "https://"),
	      "the page names a web address");
	CHECK(!strcasestr(page, "<script"), "the page holds a script element");
	CHECK(!strcasestr(page, "url("), "the style refers to a resource");
	int images = 0;
	size_t largest = 0;
	for (const char *p = page; (p = strstr(p, "src=\"")); p += 5) {
		images++;
		CHECK(strncmp(p + 5, "data:image/png;base64,", 22) == 0,
		      "src that is not a data: PNG: %.60s", p);
		size_t bytes = check_png_payload(p + 27);
		CHECK(bytes > 0, "image %d: its base64 is not a whole PNG", images);
		largest = bytes > largest ? bytes : largest;
	}
	/* the encoder writes blocks of 4096 characters: one image spans several */
	CHECK(largest > 3 * 4096, "largest image %zu bytes", largest);
	/* The overlay, 2 x (photo, labels, confidence), one render, the chart's figure and
	 * the two objects' material figures, less the deleted confidence map. */
	CHECK(images == 1 + 6 + 1 + 1 + 2 - 1, "%d images inlined", images);
	/* links: within the page, or to a file of OUTDIR beside it (master.tif, camera.icc:
	 * relative, no scheme, no "..", nothing loaded with the page) */
	int files = 0;
	for (const char *p = page; (p = strstr(p, "href=\"")); p += 6) {
		const char *q = p + 6, *end = strchr(q, '"');
		if (*q == '#')
			continue;
		files++;
		int n = end ? (int)(end - q) : 0;
		char rel[256];
		snprintf(rel, sizeof(rel), "%.*s", n, q);
		CHECK(end && !strchr(rel, ':') && rel[0] != '/' && !strstr(rel, "..") &&
		      strspn(rel, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"
		                  "-._~/%") == strlen(rel),
		      "href that leaves the output folder: %.60s", p);
	}
	/* the first object's master, the session's camera.icc and camera.ti3 */
	CHECK(files == 3, "%d links to files, expected 3", files);
}

static void check_content(const char *page)
{
	static const char *const sections[] = {"summary", "calibration", "color-accuracy",
	                                       "objects", "provenance", "warnings"};
	for (size_t i = 0; i < sizeof(sections) / sizeof(sections[0]); i++) {
		char want[64];
		snprintf(want, sizeof(want), "<section id=\"%s\">\n<h2>", sections[i]);
		CHECK(contains(page, want), "no section %s", sections[i]);
	}
	/* the colour-managed files: the master with its space, illuminant and lit clipping,
	 * none for the second object; the camera profile with its fit */
	CHECK(contains(page, "master <a href=\"object-0001/master.tif\"><code>object-0001/"
	                     "master.tif</code></a> (16-bit RGB in Adobe RGB (1998) compatible, "
	                     "its ICC profile embedded; rendered under D65, relative "
	                     "colorimetric; 7 lit pixels clipped: outside the space or brighter "
	                     "than its white)"),
	      "object-0001's master not listed with its space");
	CHECK(contains(page, ", no master (see the warnings)."), "object-0002: no master not said");
	CHECK(contains(page, "<a href=\"camera.icc\"><code>camera.icc</code></a> (ICC v2 input "
	                     "profile") && contains(page, "fitted on 18 patches, ΔE00 mean 1.93, "
	                                                   "max 4.41") &&
	      contains(page, "<a href=\"camera.ti3\">"), "camera.icc and camera.ti3 not listed");
	/* Every patch with a value, in the table; the last patch has none. */
	for (int i = 0; i < FIXTURE_PATCHES - 1; i++) {
		char d50[32], d65[32];
		snprintf(d50, sizeof(d50), "<td>%.2f</td>", 0.5 + 0.1 * i);
		snprintf(d65, sizeof(d65), "<td>%.2f</td>", 0.55 + 0.1 * i);
		CHECK(contains(page, d50) && contains(page, d65), "patch %d: %s %s missing", i, d50,
		      d65);
		CHECK(contains(page, fixture_patch_names[i]), "patch name %s missing",
		      fixture_patch_names[i]);
	}
	/* 23 values 0.50 .. 2.70: mean 1.60, nearest rank ceil(20.7) = 21 -> 2.50, max 2.70. */
	CHECK(contains(page, "mean</th><td>1.60</td><td>1.65</td>"), "mean row");
	CHECK(contains(page, "(nearest rank)</th><td>2.50</td><td>2.55</td>"), "p90 row");
	CHECK(contains(page, "maximum</th><td>2.70</td><td>2.75</td>"), "maximum row");
	CHECK(contains(page, "FADGI 4-star colour accuracy: <span class=\"pass\">pass</span>"),
	      "FADGI verdict");
	/* Held out (0.60 + 0.11 i): mean 1.81, rank 21 -> 2.80, max 3.02, beside the
	 * in-sample figures; the verdicts grade them and say so, with the caveat. */
	CHECK(contains(page, "<th scope=\"row\">mean</th><td>1.60</td><td>1.81</td>") &&
	      contains(page, "<th scope=\"row\">90th percentile</th><td>2.50</td><td>2.80</td>") &&
	      contains(page, "<th scope=\"row\">maximum</th><td>2.70</td><td>3.02</td>"),
	      "in-sample and held-out side by side");
	CHECK(contains(page, "(held-out: mean &Delta;E<sub>00</sub> 1.81, 90th percentile 2.80"),
	      "verdict on held-out figures");
	CHECK(contains(page, "not a certification"), "caveat");
	CHECK(contains(page, "ISO 19264-1 level A colour accuracy: <span class=\"pass\">pass"),
	      "ISO verdict");
	CHECK(contains(page, "Calibration: <span class=\"pass\">accepted</span>"),
	      "calibration verdict");
	CHECK(contains(page, "clipped in green (12% of its pixels)"), "flagged patch reason");
	CHECK(contains(page, "<td>1.0123</td>") && contains(page, "<td>-0.0055</td>"), "M2");
	CHECK(contains(page, "fcde2b2edba56bf408601fb721fe9b5c338d10ee429ea04fae5511b68fbf8fb9"),
	      "input sha256");
	CHECK(contains(page, "SIMSPEC-01") && contains(page, "SIM-0002"), "device serials");
	/* Text from JSON is escaped, wherever it goes. */
	CHECK(!contains(page, FIXTURE_SCRIPT), "the warning went into the page unescaped");
	CHECK(contains(page, "&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; "
	                     "&quot;quoted&quot;"), "escaped warning missing");
	CHECK(contains(page, "the flat field is 40 days old") &&
	      contains(page, "3.1% of the pixels are unknown"), "warnings missing");
	CHECK(contains(page, "3 (<a href=\"#warnings\">list</a>)"), "total warnings");
	/* Missing pieces are stated. */
	CHECK(contains(page, "not rendered: built without Embree"), "no render stated");
	CHECK(contains(page, "confidence map: not shown: the file is missing"),
	      "missing confidence map not stated");
	CHECK(contains(page, "Unchanged since the last run"), "skipped object not noted");
	/* The fixture writes no scene.json: named and said to be missing, twice. */
	CHECK(contains(page, "reflectance cube <code>object-0001/cube.hdr</code>, label map"),
	      "cube listed as present");
	const char *scene = "render scene <code>object-0002/scene.json</code> "
	                    "<span class=\"fail\">missing</span>";
	CHECK(contains(page, scene), "missing scene.json not stated");
	CHECK(contains(page, "<td>gold</td><td>300</td><td>9.77</td>") ||
	      contains(page, "gold</td><td>300</td><td>9.77</td>"), "class pixels and fraction");
}

static int run(const char *kogei, const char *outdir)
{
	pid_t pid = fork();
	if (pid == 0) {
		execl(kogei, kogei, "report", outdir, (char *)NULL);
		_exit(127);
	}
	int status = 0;
	waitpid(pid, &status, 0);
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/* Remove a key from process.json and expect the refusal to name it. */
static void check_refusal(const char *kogei, const char *outdir, const char *object,
                          const char *key, const char *named)
{
	char *path = kg_path_join(outdir, "process.json");
	json_t *root = NULL;
	kg_err err;
	CHECK(kg_json_load(path, &root, &err) == 0, "%s", err.msg);
	json_t *holder = object ? kg_json_find(root, object) : root;
	json_t *saved = json_incref(json_object_get(holder, key));
	json_object_del(holder, key);
	kg_inputs_reset(); /* each step below is a job of its own */
	CHECK(kg_json_write(root, path, &err) == 0, "%s", err.msg);

	char *page_path = kg_path_join(outdir, "report.html");
	char *before = read_text(page_path);
	kg_inputs_reset();
	int ret = kg_report_write(outdir, &err);
	CHECK(ret == KG_EINVAL, "missing %s: returned %d", named, ret);
	CHECK(strstr(err.msg, "process.json") && strstr(err.msg, named),
	      "message does not name the file and %s: %s", named, err.msg);
	char *after = read_text(page_path);
	CHECK(before && after && strcmp(before, after) == 0, "the old page was touched");
	if (kogei)
		CHECK(run(kogei, outdir) == 1, "kogei report: missing %s: not exit 1", named);

	json_object_set_new(holder, key, saved);
	kg_inputs_reset();
	CHECK(kg_json_write(root, path, &err) == 0, "%s", err.msg);
	json_decref(root);
	free(before);
	free(after);
	free(page_path);
	free(path);
}

static int count(const char *page, const char *needle)
{
	int n = 0;
	for (const char *p = page; (p = strstr(p, needle)); p += strlen(needle))
		n++;
	return n;
}

/* Images process.json names are read only inside OUTDIR: an absolute path, a "../"
 * path and a path through a symbolic link to a folder elsewhere (each naming a real
 * PNG), and /etc/passwd, are left out with a warning naming the path; the page is still
 * written (exit 0). */
static void check_outside(const char *kogei, const char *outdir)
{
	char outside[256], cmd[1024];
	snprintf(outside, sizeof(outside), "%s-outside", outdir);
	snprintf(cmd, sizeof(cmd), "mkdir -p '%s' && cp '%s/object-0001/photo.png' '%s/secret.png' "
	         "&& ln -s '%s' '%s/linked'", outside, outdir, outside, outside, outdir);
	CHECK(system(cmd) == 0, "%s", cmd);
	char *path = kg_path_join(outdir, "process.json");
	char *page_path = kg_path_join(outdir, "report.html");
	kg_err err = {{0}};
	kg_inputs_reset();
	CHECK(kg_report_write(outdir, &err) == 0, "%s", err.msg);
	char *page = read_text(page_path);
	int before = page ? count(page, "data:image/png;base64,") : 0;
	free(page);

	json_t *root = NULL;
	CHECK(kg_json_load(path, &root, &err) == 0, "%s", err.msg);
	char abs[300], up[300];
	snprintf(abs, sizeof(abs), "%s/secret.png", outside);
	snprintf(up, sizeof(up), "../%s/secret.png", strrchr(outside, '/') + 1);
	json_t *o0 = kg_json_find(root, "objects[0]"), *o1 = kg_json_find(root, "objects[1]");
	json_object_set_new(o0, "photo", json_string(abs));
	json_object_set_new(o0, "labels_png", json_string(up));
	json_object_set_new(o1, "photo", json_string("linked/secret.png"));
	json_object_set_new(json_object_get(root, "calibration"), "overlay",
	                    json_string("/etc/passwd"));
	json_object_set_new(o1, "cube", json_string("/etc/passwd"));
	kg_inputs_reset();
	CHECK(kg_json_write(root, path, &err) == 0, "%s", err.msg);
	kg_inputs_reset();
	int ret = kg_report_write(outdir, &err);
	CHECK(ret == 0, "kg_report_write with paths outside OUTDIR: %s", err.msg);
	page = read_text(page_path);
	if (page) {
		int after = count(page, "data:image/png;base64,");
		CHECK(after == before - 4, "%d images inlined, expected %d (4 outside OUTDIR left out)",
		      after, before - 4);
		char want[600];
		snprintf(want, sizeof(want), "photograph: not shown: %s names &#39;%s&#39;, expected a "
		         "path inside %s", path, abs, outdir);
		CHECK(contains(page, want), "no warning for the absolute path: %s", want);
		snprintf(want, sizeof(want), "label map: not shown: %s names &#39;%s&#39;, expected", path,
		         up);
		CHECK(contains(page, want), "no warning for the ../ path: %s", want);
		CHECK(contains(page, "chart overlay: not shown: ") &&
		      contains(page, "names &#39;/etc/passwd&#39;, expected a path inside"),
		      "no warning for /etc/passwd");
		snprintf(want, sizeof(want), "<span class=\"fail\">warning</span> photograph: not "
		         "shown: %s/linked: is a symbolic link", outdir);
		CHECK(contains(page, want), "no warning for the linked folder: %s", want);
		CHECK(contains(page, "not inside the output folder: not read"),
		      "the cube at /etc/passwd is not flagged");
	}
	free(page);
	if (kogei)
		CHECK(run(kogei, outdir) == 0, "kogei report with paths outside OUTDIR: not exit 0");
	json_decref(root);
	free(path);
	free(page_path);
	snprintf(cmd, sizeof(cmd), "rm -rf '%s' '%s/linked'", outside, outdir);
	CHECK(system(cmd) == 0, "%s", cmd);
}

int main(int argc, char **argv)
{
	const char *kogei = argc > 1 ? argv[1] : NULL;
	char outdir[] = "/tmp/kg_report_XXXXXX";
	if (!mkdtemp(outdir)) {
		perror("mkdtemp");
		return 1;
	}
	CHECK(fixture_write(outdir) == 0, "fixture");
	char *conf = kg_path_join(outdir, "object-0001/confidence.png");
	CHECK(unlink(conf) == 0, "unlink %s", conf);
	free(conf);

	kg_err err = {{0}};
	int ret = kg_report_write(outdir, &err);
	CHECK(ret == 0, "kg_report_write: %s", err.msg);
	char *page_path = kg_path_join(outdir, "report.html");
	char *page = ret ? NULL : read_text(page_path);
	if (page) {
		check_self_contained(page);
		check_content(page);
	}
	free(page);
	free(page_path);
	if (kogei)
		CHECK(run(kogei, outdir) == 0, "kogei report on the fixture failed");

	check_refusal(kogei, outdir, "calibration", "cond_M2", "calibration.cond_M2");
	check_refusal(kogei, outdir, NULL, "warnings", "'warnings'");
	check_refusal(kogei, outdir, "objects[1]", "classes", "objects[1].classes");
	check_refusal(kogei, outdir, "calibration.patches[5]", "de00_d50",
	              "calibration.patches[5].de00_d50");
	check_outside(kogei, outdir);

	char cmd[128];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", outdir);
	if (kg_test_failures == 0 && system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", outdir);
	else if (kg_test_failures)
		fprintf(stderr, "left %s for inspection\n", outdir);
	return kg_test_done("report-html");
}
