/* `kogei calib reference` and `kogei calib camera` end to end on a synthetic chart
 * written here (no reference data needed):
 *  - the two commands succeed, write files that load, and M2 comes out as T^-1;
 *  - refusals exit 1 with the cause on standard error and leave no file behind;
 *  - bad usage exits 2; --help exits 0.
 * Argument: the path of the kogei program. */
#include <fcntl.h>
#include <stdarg.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "calib_fixture.h"
#include "kg_test.h"

static const char *kogei;
static char dir[] = "/tmp/kogei-calib-cli-XXXXXX";

static const char *path(const char *name)
{
	static char ring[8][512];
	static int next;
	char *p = ring[next++ % 8];
	snprintf(p, sizeof(ring[0]), "%s/%s", dir, name);
	return p;
}

/* Run kogei with the arguments (NULL-terminated); its stdout and stderr are kept in
 * out and err. Returns the exit status. */
static int run(char *out, char *err, size_t len, ...)
{
	char *argv[32];
	int n = 0;
	argv[n++] = (char *)kogei;
	va_list ap;
	va_start(ap, len);
	for (char *a; n < 31 && (a = va_arg(ap, char *));)
		argv[n++] = a;
	va_end(ap);
	argv[n] = NULL;
	char out_path[600], err_path[600];
	snprintf(out_path, sizeof(out_path), "%s", path("stdout.txt"));
	snprintf(err_path, sizeof(err_path), "%s", path("stderr.txt"));
	pid_t pid = fork();
	if (pid == 0) {
		int fo = open(out_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
		int fe = open(err_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
		dup2(fo, 1);
		dup2(fe, 2);
		execv(kogei, argv);
		_exit(127);
	}
	int status = 0;
	waitpid(pid, &status, 0);
	kg_test_slurp(out_path, out, len);
	kg_test_slurp(err_path, err, len);
	unlink(out_path);
	unlink(err_path);
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

#define RUN(...) run(out, errs, sizeof(out), __VA_ARGS__, (char *)NULL)

static int exists(const char *p)
{
	struct stat st;
	return stat(p, &st) == 0;
}

/* Files in the scratch directory. */
static int count_files(void)
{
	char cmd[700], buf[64] = "";
	snprintf(cmd, sizeof(cmd), "ls -A '%s' | wc -l", dir);
	FILE *fp = popen(cmd, "r");
	if (!fp)
		return -1;
	if (!fgets(buf, sizeof(buf), fp))
		buf[0] = '\0';
	pclose(fp);
	return atoi(buf);
}

static void write_inputs(void)
{
	kg_err err = {{0}};
	kg_patchset *chart = fx_chart(24, 0.002, 3), *site = chart ? fx_site(chart) : NULL;
	if (!site) {
		CHECK(0, "fixture");
		return;
	}
	int ret = kg_patchset_write(path("spectra.cgats"), chart, KG_PATCH_SPECTRA, NULL, &err);
	if (!ret)
		ret = kg_patchset_write(path("rgb.cgats"), chart, KG_PATCH_RGB, NULL, &err);
	if (!ret)
		ret = kg_patchset_write(path("site.cgats"), site, KG_PATCH_RGB, NULL, &err);
	/* The site chart with P7 clipped. */
	site->rgb[6][0] = 0.995;
	if (!ret)
		ret = kg_patchset_write(path("clipped.cgats"), site, KG_PATCH_RGB, NULL, &err);
	/* Six grey patches. */
	kg_patchset *grey = NULL;
	if (!ret)
		ret = kg_patchset_new(6, KG_PATCH_RGB, &grey, &err);
	for (int i = 0; !ret && i < 6; i++) {
		double level = 0.1 + 0.12 * i;
		grey->rgb[i][0] = 0.40 * level;
		grey->rgb[i][1] = 0.50 * level;
		grey->rgb[i][2] = 0.30 * level;
		ret = kg_patchset_set_id(grey, i, chart->ids[i], &err);
	}
	if (!ret)
		ret = kg_patchset_write(path("grey.cgats"), grey, KG_PATCH_RGB, NULL, &err);
	CHECK(ret == 0, "writing inputs: %s", err.msg);
	kg_patchset_free(&grey);
	kg_patchset_free(&chart);
	kg_patchset_free(&site);
}

int main(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: %s KOGEI\n", argv[0]);
		return 1;
	}
	kogei = argv[1];
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	static char out[65536], errs[65536];
	write_inputs();
	char *spectra = strdup(path("spectra.cgats")), *rgb = strdup(path("rgb.cgats"));
	char *site = strdup(path("site.cgats")), *ref = strdup(path("ref.json"));
	char *cam = strdup(path("cam.json"));

	int rc = RUN("calib", "reference", "--spectra", spectra, "--rgb", rgb, "--basis", "auto",
	             "--method", "auto", "-o", ref);
	printf("%s", out);
	CHECK(rc == 0, "calib reference: exit %d: %s", rc, errs);
	CHECK(strstr(out, "leave-one-out spectral RMSE by K") && strstr(out, "rootpoly3"),
	      "report lacks the LOO table: %s", out);
	kg_reference *r = NULL;
	kg_err err = {{0}};
	CHECK(kg_reference_load(ref, &r, &err) == 0, "load: %s", err.msg);
	CHECK(r && r->K == 3 && r->basis_auto, "K = %d", r ? r->K : -1);
	kg_reference_free(&r);

	rc = RUN("calib", "camera", "--reference", ref, "--rgb", site, "-o", cam);
	printf("%s", out);
	CHECK(rc == 0, "calib camera: exit %d: %s", rc, errs);
	CHECK(strstr(out, "condition number") && strstr(out, "residual"), "report: %s", out);
	kg_camera_calib *c = NULL;
	CHECK(kg_camera_load(cam, &c, &err) == 0, "load: %s", err.msg);
	if (c) {
		/* rho_site = T rho: M2 = T^-1, i.e. M2 T = I. */
		for (int a = 0; a < 3; a++)
			for (int b = 0; b < 3; b++) {
				double v = 0;
				for (int k = 0; k < 3; k++)
					v += c->M2[3 * a + k] * fx_T[3 * k + b];
				CHECK_NEAR(v, a == b, 1e-9, "M2 T = I");
			}
	}
	kg_camera_calib_free(&c);

	/* JSON to standard output, report to standard error. */
	rc = RUN("calib", "camera", "--reference", ref, "--rgb", site, "--method", "linear", "-o",
	         "-");
	CHECK(rc == 0 && strstr(out, "\"format\": \"kogei-camera/1\"") &&
	          strstr(out, "\"method\": \"linear\"") && strstr(errs, "condition number"),
	      "-o -: exit %d", rc);

	/* Refusals: exit 1, the cause on stderr, nothing left behind. */
	int before = count_files();
	char *bad = strdup(path("bad.json"));
	rc = RUN("calib", "camera", "--reference", ref, "--rgb", path("clipped.cgats"), "-o", bad);
	CHECK(rc == 1 && strstr(errs, "clipped") && strstr(errs, "P7"), "clipped: %d %s", rc, errs);
	rc = RUN("calib", "camera", "--reference", ref, "--rgb", path("clipped.cgats"), "--exclude",
	         "P7", "-o", bad);
	CHECK(rc == 0, "clipped with --exclude P7: %d %s", rc, errs);
	unlink(bad);
	rc = RUN("calib", "camera", "--reference", ref, "--rgb", path("grey.cgats"), "-o", bad);
	CHECK(rc == 1 && strstr(errs, "three independent colours") && strstr(errs, "neutral"),
	      "grey: %d %s", rc,
	      errs);
	rc = RUN("calib", "camera", "--reference", spectra, "--rgb", site, "-o", bad);
	CHECK(rc == 1 && strstr(errs, "spectra.cgats"), "not JSON: %d %s", rc, errs);
	rc = RUN("calib", "reference", "--spectra", spectra, "--rgb", path("nothere.cgats"), "-o",
	         bad);
	CHECK(rc == 1 && strstr(errs, "nothere.cgats"), "missing file: %d %s", rc, errs);
	CHECK(!exists(bad) && count_files() == before, "files left behind after refusals");

	/* Usage. */
	rc = RUN("calib", "reference", "--spectra", spectra, "--rgb", rgb);
	CHECK(rc == 2 && strstr(errs, "-o"), "no -o: %d %s", rc, errs);
	rc = RUN("calib", "reference", "--spectra", spectra, "--rgb", rgb, "--basis", "9", "-o", bad);
	CHECK(rc == 2 && strstr(errs, "--basis 9"), "--basis 9: %d %s", rc, errs);
	rc = RUN("calib", "camera", "--reference", ref, "--rgb", site, "--method", "magic", "-o",
	         bad);
	CHECK(rc == 2 && strstr(errs, "magic"), "--method magic: %d %s", rc, errs);
	rc = RUN("calib", "camera", "--help");
	CHECK(rc == 0 && strstr(out, "M2 = rho0 pinv(rho_r)"), "--help: %d", rc);

	char cmd[700];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", dir);
	free(spectra);
	free(rgb);
	free(site);
	free(ref);
	free(cam);
	free(bad);
	return kg_test_done("calib-cli");
}
