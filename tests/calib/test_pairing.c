/* Pairing two patch files checked by colour (calib/pairing.c) on real charts: the
 * measured XYZ of ArgyllCMS's reference charts (argyll-ref: the CMP Digital Target 4,
 * the ColorChecker DC and SG) against their own RGB (sRGB-decoded) as the camera's
 * values. The correct pairing is accepted; the camera file named one number off,
 * read down its columns, or with two patches swapped is refused, with the pairing
 * that fits. And every --id-pairing name parses back to its pairing. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib_private.h"
#include "kg_test.h"

#define ARGYLL "/usr/share/color/argyll/ref"

static void names(void)
{
	for (int p = 0; p < KG_ID_PAIRING_COUNT; p++) {
		char name[64];
		kg_id_pairing back = KG_ID_PAIRING_COUNT;
		kg_err err = {{0}};
		kg_id_pairing_name((kg_id_pairing)p, "spectra", "rgb", name, sizeof(name));
		CHECK(kg_id_pairing_parse(name, "spectra", "rgb", &back, &err) == 0 && (int)back == p,
		      "%s parsed as %d: %s", name, (int)back, err.msg);
	}
	kg_id_pairing out;
	kg_err err = {{0}};
	CHECK(kg_id_pairing_parse("spectra-by-number", "reference", "rgb", &out, &err) != 0 &&
	      strstr(err.msg, "reference-by-number"),
	      "calib camera's roles: %s", err.msg);
}

static double srgb_decode(double v)
{
	return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}

typedef struct idkey {
	int letter, number, index;
} idkey;

static int by_letter(const void *pa, const void *pb)
{
	const idkey *a = pa, *b = pb;
	return a->letter != b->letter ? a->letter - b->letter : a->number - b->number;
}

static int by_number(const void *pa, const void *pb)
{
	const idkey *a = pa, *b = pb;
	return a->number != b->number ? a->number - b->number : a->letter - b->letter;
}

/* ids renamed as another convention would: numbers counted from 0 (A01 -> A00, 1 ->
 * 0), or (down) the grid read down its columns and named along its rows: the k-th
 * patch by number then letter gets the k-th id by letter then number. */
static void renamed(char **ids, int n, int down, char **out)
{
	idkey *l = malloc((size_t)n * sizeof(idkey)), *c = malloc((size_t)n * sizeof(idkey));
	for (int i = 0; i < n; i++) {
		int has = ids[i][0] >= 'A' && ids[i][0] <= 'Z';
		l[i] = c[i] = (idkey){has ? ids[i][0] : 0, atoi(ids[i] + has), i};
	}
	qsort(l, (size_t)n, sizeof(idkey), by_letter);
	qsort(c, (size_t)n, sizeof(idkey), by_number);
	for (int k = 0; k < n; k++) {
		char buf[16];
		if (down)
			snprintf(buf, sizeof(buf), "%s", ids[l[k].index]);
		else if (l[k].letter)
			snprintf(buf, sizeof(buf), "%c%d", l[k].letter, l[k].number - 1);
		else
			snprintf(buf, sizeof(buf), "%d", l[k].number - 1);
		out[down ? c[k].index : l[k].index] = strdup(buf);
	}
	free(l);
	free(c);
}

/* The chart's ids: its SAMPLE_LOC when that names a letter-and-number grid (the
 * ColorChecker DC's A01..T12, the SG's A01..N10), else its patch set's (SAMPLE_ID). */
static char **chart_ids(const char *path, const kg_patchset *ps)
{
	kg_err err = {{0}};
	kg_cgats *cg = NULL;
	char **ids = calloc((size_t)ps->n, sizeof(char *));
	int f = -1;
	if (kg_cgats_read(path, &cg, &err) == 0)
		f = kg_cgats_field(cg->tables[0], "SAMPLE_LOC");
	for (int i = 0; i < ps->n; i++) {
		const char *loc = f >= 0 ? cg->tables[0]->cells[(size_t)i * cg->tables[0]->nfields + f]
		                         : NULL;
		int grid = loc && loc[0] >= 'A' && loc[0] <= 'Z' && loc[1] >= '0' && loc[1] <= '9';
		f = grid ? f : -1;
		ids[i] = strdup(grid ? loc : ps->ids[i]);
	}
	if (f < 0)
		for (int i = 0; i < ps->n; i++) {
			free(ids[i]);
			ids[i] = strdup(ps->ids[i]);
		}
	kg_cgats_free(&cg);
	return ids;
}

/* One chart: its XYZ against its sRGB-decoded RGB, paired and mispaired. */
static void chart(const char *file)
{
	char path[512];
	snprintf(path, sizeof(path), "%s/%s", ARGYLL, file);
	if (!kg_test_file_exists(path)) {
		printf("note: %s missing (argyll-ref): not checked\n", path);
		return;
	}
	kg_err err = {{0}};
	kg_patchset *ps = NULL;
	if (kg_patchset_read(path, KG_PATCH_KEEP_SCALE, &ps, &err) || !ps->rgb || !ps->xyz) {
		CHECK(0, "%s: RGB and XYZ expected: %s", file, err.msg);
		kg_patchset_free(&ps);
		return;
	}
	int n = ps->n;
	double top = 0, (*cam)[3] = malloc((size_t)n * sizeof(*cam));
	for (int i = 0; i < n; i++)
		for (int c = 0; c < 3; c++)
			top = fmax(top, ps->rgb[i][c]);
	top = top > 101 ? 255 : 100;
	for (int i = 0; i < n; i++)
		for (int c = 0; c < 3; c++)
			cam[i][c] = srgb_decode(ps->rgb[i][c] / top);
	/* a device value of 0 (the DC's saturated column S) is out of gamut, not a reading */
	kg_patchset *camera = NULL;
	CHECK(kg_patchset_new(n, KG_PATCH_RGB, &camera, &err) == 0, "%s", err.msg);
	memcpy(camera->rgb, cam, (size_t)n * sizeof(*cam));
	char **ids = chart_ids(path, ps), **moved = calloc((size_t)n, sizeof(char *));
	int grid = ids[0][0] >= 'A' && ids[0][0] <= 'Z';
	calib_pair_side a = {0}, b = {0};
	calib_pair_result r = {0};
	CHECK(calib_pair_side_new(file, "spectra", "its XYZ", ids, n, (const double(*)[3])ps->xyz,
	                          &a, &err) == 0 &&
	          calib_pair_side_new("camera", "rgb", "", ids, n, (const double(*)[3])cam, &b,
	                              &err) == 0,
	      "%s", err.msg);
	calib_pair_side_skip(&b, NULL, 0, camera, 1);
	int ok = calib_pair_check(&a, &b, KG_ID_PAIRING_NAMES, 1, "--id-pairing", &r, &err) == 0;
	CHECK(ok && r.npairs == n && r.misfit < KG_CALIB_PAIR_MAX_MISFIT, "%s: correct pairing: %s",
	      file, err.msg);
	double correct = r.misfit;
	calib_pair_result_free(&r);

	/* the camera file numbered from 0, then (a grid) read down its columns */
	static const char *const expect[2] = {"--id-pairing grid-order", "-by-number"};
	static const char *const what[2] = {"numbered from 0", "numbered down its columns"};
	double wrong[2] = {NAN, NAN};
	for (int down = 0; down < 1 + grid; down++) {
		renamed(ids, n, down, moved);
		b.ids = moved;
		kg_err e2 = {{0}};
		int ret = calib_pair_check(&a, &b, KG_ID_PAIRING_NAMES, 1, "--id-pairing", &r, &e2);
		CHECK(ret == KG_EINVAL && strstr(e2.msg, expect[down]) && strstr(e2.msg, file),
		      "%s %s: %d %s", file, what[down], ret, e2.msg);
		const char *m = strstr(e2.msg, "camera values by ");
		wrong[down] = m ? atof(m + strlen("camera values by ")) : NAN;
		calib_pair_result_free(&r);
		for (int i = 0; i < n; i++)
			free(moved[i]);
	}

	/* two patches of clearly different colour swapped in the camera file: the first,
	 * and the one whose colour is farthest from it relative to both (of those with a
	 * reading in every channel) */
	b.ids = ids;
	int i = 0, j = 1;
	double far = 0;
	for (int k = 1; k < n; k++) {
		double d = 0, ni = 0, nk = 0;
		if (b.skip[k])
			continue;
		for (int c = 0; c < 3; c++) {
			d += (ps->xyz[k][c] - ps->xyz[i][c]) * (ps->xyz[k][c] - ps->xyz[i][c]);
			ni += ps->xyz[i][c] * ps->xyz[i][c];
			nk += ps->xyz[k][c] * ps->xyz[k][c];
		}
		if (d / (ni + nk) > far) {
			far = d / (ni + nk);
			j = k;
		}
	}
	double s[3];
	memcpy(s, b.colour[i], sizeof(s));
	memcpy(b.colour[i], b.colour[j], sizeof(s));
	memcpy(b.colour[j], s, sizeof(s));
	kg_err e3 = {{0}};
	char want_i[64], want_j[64];
	snprintf(want_i, sizeof(want_i), ", %s -> ", ids[i]);
	snprintf(want_j, sizeof(want_j), ", %s -> ", ids[j]);
	int ret = calib_pair_check(&a, &b, KG_ID_PAIRING_NAMES, 1, "--id-pairing", &r, &e3);
	/* either is named; its partner may be another patch of the same colour (the
	 * charts repeat their white and black) */
	const char *list = strstr(e3.msg, "(error; as paired): ");
	char named[1100] = "";
	if (list)
		snprintf(named, sizeof(named), ", %s", list + strlen("(error; as paired): "));
	CHECK(ret == KG_EINVAL && list && (strstr(named, want_i) || strstr(named, want_j)),
	      "%s: %s and %s swapped: %s", file, ids[i], ids[j], e3.msg);
	calib_pair_result_free(&r);
	char down[64] = "";
	if (grid)
		snprintf(down, sizeof(down), ", numbered down its columns (%.1f %%)", wrong[1]);
	printf("%s (%d patches, ids %s..%s): misfit %.1f %% paired correctly; refused numbered "
	       "from 0 (%.1f %%)%s, and with %s and %s swapped\n", file, n, ids[0], ids[n - 1],
	       100 * correct, wrong[0], down, ids[i], ids[j]);
	calib_pair_side_free(&a);
	calib_pair_side_free(&b);
	calib_strv_free(ids, n);
	free(moved);
	free(cam);
	kg_patchset_free(&camera);
	kg_patchset_free(&ps);
}

int main(void)
{
	names();
	chart("CMP_Digital_Target-4.ti2");
	chart("ColorCheckerDC.ti2");
	chart("ColorCheckerSG.ti2");
	return kg_test_done("calib-pairing");
}
