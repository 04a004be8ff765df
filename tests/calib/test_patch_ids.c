/* Chart files people have: patch ids match through aliases both ways (ArgyllCMS
 * chartread's 1..24, the .cht's A1..D6, kogei's A01..D06), checked against the
 * SAMPLE_LOC column of argyll-ref's ColorChecker.ti2 and ColorCheckerSG.ti2 and the
 * ids of their .cht templates; X-Rite's spectral field names (i1Profiler
 * SPECTRAL_NM380.., MeasureTool nm380..) read as the same spectra as SPEC_<nm>. */
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_calib.h"
#include "kg_core.h"
#include "kg_test.h"

#define ARGYLL "/usr/share/color/argyll/ref"

/* Same letter and number, whatever the padding. */
static int same_patch(const char *a, const char *b)
{
	while (*a && *b && isalpha((unsigned char)*a) && toupper((unsigned char)*a) ==
	       toupper((unsigned char)*b))
		a++, b++;
	return !isalpha((unsigned char)*a) && !isalpha((unsigned char)*b) && atoi(a) == atoi(b) &&
	       atoi(a) > 0;
}

static void synthetic(void)
{
	char *num[24], *pad[24], *bare[24], buf[3][24][8];
	for (int i = 0; i < 24; i++) {
		snprintf(buf[0][i], 8, "%d", i + 1);
		snprintf(buf[1][i], 8, "%c%02d", 'A' + i / 6, i % 6 + 1);
		snprintf(buf[2][i], 8, "%c%d", 'a' + i / 6, i % 6 + 1);
		num[i] = buf[0][i];
		pad[i] = buf[1][i];
		bare[i] = buf[2][i];
	}
	int m[24];
	const char *rule = "x";
	CHECK(kg_patch_ids_match(pad, 24, pad, 24, m, &rule) == 24 && rule == NULL,
	      "exact ids: all matched, no rule");
	CHECK(kg_patch_ids_match(num, 24, pad, 24, m, &rule) == 24 && rule, "1..24 to A01..D06");
	for (int i = 0; i < 24; i++)
		CHECK(m[i] == i, "patch %s matched %s, expected %s", num[i], m[i] >= 0 ? pad[m[i]] : "-",
		      pad[i]);
	CHECK(kg_patch_ids_match(pad, 24, num, 24, m, &rule) == 24, "A01..D06 to 1..24");
	for (int i = 0; i < 24; i++)
		CHECK(m[i] == i, "patch %s: matched index %d, expected %d", pad[i], m[i], i);
	CHECK(kg_patch_ids_match(bare, 24, pad, 24, m, &rule) == 24 && rule &&
	      strstr(rule, "A1 = A01"), "a1..d6 to A01..D06");
	for (int i = 0; i < 24; i++)
		CHECK(m[i] == i, "patch %s: matched index %d, expected %d", bare[i], m[i], i);
	/* a site file with patches left out: the grid's width comes from the ids present */
	char *some[3] = {buf[0][0], buf[0][6], buf[0][23]};
	CHECK(kg_patch_ids_match(some, 3, pad, 24, m, NULL) == 3 && m[0] == 0 && m[1] == 6 &&
	      m[2] == 23, "1, 7, 24 to A01, B01, D06: %d %d %d", m[0], m[1], m[2]);
	/* a grid whose width cannot be told (its last column missing: A01..D05, numbers up
	 * to 24 would need 5 letters) pairs nothing rather than something wrong */
	char *nolast[20];
	for (int i = 0, k = 0; i < 24; i++)
		if (i % 6 != 5)
			nolast[k++] = pad[i];
	CHECK(kg_patch_ids_match(num, 24, nolast, 20, m, NULL) == 0,
	      "1..24 against A01..D05: nothing paired");
	char *one[1] = {"B1"};
	CHECK(kg_patch_ids_match(one, 1, num, 24, m, NULL) == 0, "B1 alone against 1..24: no pair");
	/* ids of another kind are not forced onto a grid */
	char *tcs[2] = {"TCS01", "TCS02"};
	CHECK(kg_patch_ids_match(tcs, 2, num, 24, m, NULL) == 0 && m[0] == -1 && m[1] == -1,
	      "TCS01 matches nothing of 1..24");
	char *mixed[2] = {"white", "7"};
	CHECK(kg_patch_ids_match(mixed, 2, pad, 24, m, NULL) == 0, "a mixed file is not aligned");
}

/* SAMPLE_ID n of a .ti2 must match the .cht's id that SAMPLE_LOC names. */
static void argyll_pair(const char *ti2, const char *cht)
{
	char p1[512], p2[512];
	snprintf(p1, sizeof(p1), "%s/%s", ARGYLL, ti2);
	snprintf(p2, sizeof(p2), "%s/%s", ARGYLL, cht);
	if (!kg_test_file_exists(p1) || !kg_test_file_exists(p2)) {
		printf("note: %s or %s missing (argyll-ref): not checked\n", ti2, cht);
		return;
	}
	kg_err err = {{0}};
	kg_cgats *cg = NULL;
	kg_chart_layout *l = NULL;
	CHECK(kg_cgats_read(p1, &cg, &err) == 0, "%s", err.msg);
	CHECK(kg_chart_layout_load_cht(p2, 0, &l, &err) == 0, "%s", err.msg);
	if (!cg || !l) {
		kg_cgats_free(&cg);
		kg_chart_layout_free(&l);
		return;
	}
	const kg_cgats_table *t = cg->tables[0];
	int fid = -1, floc = -1;
	for (int f = 0; f < t->nfields; f++) {
		if (strcmp(t->fields[f], "SAMPLE_ID") == 0)
			fid = f;
		if (strcmp(t->fields[f], "SAMPLE_LOC") == 0)
			floc = f;
	}
	CHECK(fid >= 0 && floc >= 0, "%s: SAMPLE_ID and SAMPLE_LOC", ti2);
	int n = t->nsets;
	char **ids = calloc((size_t)n, sizeof(char *));
	char **cids = calloc((size_t)l->npatches, sizeof(char *));
	int *m = calloc((size_t)n, sizeof(int));
	for (int i = 0; i < n && fid >= 0; i++)
		ids[i] = t->cells[(size_t)i * t->nfields + fid];
	for (int j = 0; j < l->npatches; j++)
		cids[j] = l->patches[j].id;
	const char *rule = NULL;
	int got = fid >= 0 ? kg_patch_ids_match(ids, n, cids, l->npatches, m, &rule) : 0;
	CHECK(got == n, "%s against %s: %d of %d matched", ti2, cht, got, n);
	/* argyll-ref's ColorCheckerSG.ti2 numbers C07 "26" like C06 (27 is missing): a
	 * repeated id is the file's error, not the rule's, and is left out */
	int agree = 0, repeated = 0;
	for (int i = 0; i < n && got == n && floc >= 0; i++) {
		const char *loc = t->cells[(size_t)i * t->nfields + floc];
		int dup = 0;
		for (int k = 0; k < i; k++)
			dup |= strcmp(ids[k], ids[i]) == 0;
		if (dup) {
			printf("note: %s: SAMPLE_ID %s repeated (SAMPLE_LOC %s): left out\n", ti2, ids[i],
			       loc);
			repeated++;
			continue;
		}
		int ok = m[i] >= 0 && same_patch(loc, cids[m[i]]);
		agree += ok;
		CHECK(ok, "%s: SAMPLE_ID %s (SAMPLE_LOC %s) matched %s", ti2, ids[i], loc,
		      m[i] >= 0 ? cids[m[i]] : "nothing");
	}
	CHECK(agree + repeated == n && repeated <= 1, "%s: %d agree, %d repeated", ti2, agree,
	      repeated);
	printf("%s (ids %s..%s) against %s (ids %s..%s): %d of %d as SAMPLE_LOC says (%s)\n", ti2,
	       ids[0], ids[n - 1], cht, cids[0], cids[l->npatches - 1], agree, n - repeated,
	       rule ? rule : "exact");
	/* and the other way */
	int *back = calloc((size_t)l->npatches, sizeof(int));
	got = kg_patch_ids_match(cids, l->npatches, ids, n, back, NULL);
	CHECK(got == n - repeated, "%s against %s: %d of %d matched", cht, ti2, got, n - repeated);
	for (int j = 0; j < l->npatches; j++)
		CHECK(back[j] < 0 || m[back[j]] == j, "%s: %s -> %s -> back", cht, cids[j],
		      ids[back[j]]);
	free(back);
	free(ids);
	free(cids);
	free(m);
	kg_cgats_free(&cg);
	kg_chart_layout_free(&l);
}

/* kogei's bundled layout: ids A01..D06 and the aliases 1..24 it carries agree with
 * the rule. */
static void bundled_layout(void)
{
	kg_err err = {{0}};
	kg_chart_layout *l = NULL;
	CHECK(kg_chart_layout_load("colorchecker24-frame", &l, &err) == 0, "%s", err.msg);
	if (!l)
		return;
	int n = l->npatches;
	char **ids = calloc((size_t)n, sizeof(char *)), **al = calloc((size_t)n, sizeof(char *));
	int *m = calloc((size_t)n, sizeof(int));
	for (int i = 0; i < n; i++) {
		ids[i] = l->patches[i].id;
		al[i] = l->patches[i].alias;
	}
	CHECK(kg_patch_ids_match(al, n, ids, n, m, NULL) == n, "aliases to ids");
	for (int i = 0; i < n; i++)
		CHECK(m[i] == i, "alias %s of %s matched %s", al[i], ids[i], m[i] >= 0 ? ids[m[i]] : "-");
	free(ids);
	free(al);
	free(m);
	kg_chart_layout_free(&l);
}

static void write_file(const char *path, const char *text)
{
	FILE *fp = fopen(path, "w");
	CHECK(fp && fputs(text, fp) >= 0 && fclose(fp) == 0, "write %s", path);
}

/* The same three spectra (10 nm, 380-730) under three naming conventions. */
static void xrite_names(const char *dir)
{
	static const char *const conv[3][2] = {
		{"SPEC_", "CGATS.17"},        /* ArgyllCMS / CGATS.17 */
		{"SPECTRAL_NM", "CGATS.17"},  /* X-Rite i1Profiler */
		{"nm", "CGATS.17"},           /* X-Rite MeasureTool */
	};
	kg_patchset *ps[3] = {NULL, NULL, NULL};
	for (int c = 0; c < 3; c++) {
		char path[512], text[16384];
		size_t at = 0;
		snprintf(path, sizeof(path), "%s/xrite%d.txt", dir, c);
		at += (size_t)snprintf(text + at, sizeof(text) - at,
		                       "%s\nORIGINATOR \"test\"\nNUMBER_OF_FIELDS 38\n"
		                       "BEGIN_DATA_FORMAT\nSAMPLE_ID SAMPLE_NAME", conv[c][1]);
		for (int nm = 380; nm <= 730; nm += 10)
			at += (size_t)snprintf(text + at, sizeof(text) - at, " %s%d", conv[c][0], nm);
		at += (size_t)snprintf(text + at, sizeof(text) - at,
		                       "\nEND_DATA_FORMAT\nNUMBER_OF_SETS 3\nBEGIN_DATA\n");
		for (int i = 0; i < 3; i++) {
			at += (size_t)snprintf(text + at, sizeof(text) - at, "A%d P%d", i + 1, i + 1);
			for (int nm = 380; nm <= 730; nm += 10) {
				double v = 0.05 + 0.3 * i + 0.5 * (nm - 380) / 350.0 * (i == 1 ? -0.2 : 1);
				/* i1Profiler writes fractions, MeasureTool percent: both read as fractions */
				at += (size_t)snprintf(text + at, sizeof(text) - at, " %.6f",
				                       c == 2 ? 100 * v : v);
			}
			at += (size_t)snprintf(text + at, sizeof(text) - at, "\n");
		}
		snprintf(text + at, sizeof(text) - at, "END_DATA\n");
		write_file(path, text);
		kg_err err = {{0}};
		CHECK(kg_patchset_read(path, 0, &ps[c], &err) == 0, "%s: %s", conv[c][0], err.msg);
		CHECK(ps[c] && ps[c]->spectra, "%s fields read as spectra", conv[c][0]);
	}
	for (int c = 1; c < 3; c++) {
		if (!ps[0] || !ps[c] || !ps[0]->spectra || !ps[c]->spectra)
			continue;
		double worst = 0;
		for (int i = 0; i < 3; i++)
			for (int l = 0; l < KG_NBANDS; l++)
				worst = fmax(worst, fabs(ps[c]->spectra[i].v[l] - ps[0]->spectra[i].v[l]));
		CHECK(worst < 1e-6, "%s: differs from SPEC_ by %g", conv[c][0], worst);
		printf("%s<nm> fields: the SPEC_<nm> spectra within %.2g\n", conv[c][0], worst);
	}
	for (int c = 0; c < 3; c++)
		kg_patchset_free(&ps[c]);
	/* a malformed X-Rite name is refused, naming the field */
	char path[512];
	snprintf(path, sizeof(path), "%s/bad.txt", dir);
	write_file(path, "CGATS.17\nNUMBER_OF_FIELDS 3\nBEGIN_DATA_FORMAT\nSAMPLE_ID SPECTRAL_NM400 "
	                 "SPECTRAL_NMx\nEND_DATA_FORMAT\nNUMBER_OF_SETS 1\nBEGIN_DATA\nA1 0.5 0.5\n"
	                 "END_DATA\n");
	kg_patchset *bad = NULL;
	kg_err err = {{0}};
	CHECK(kg_patchset_read(path, 0, &bad, &err) != 0 && strstr(err.msg, "SPECTRAL_NMx") &&
	      strstr(err.msg, "bad.txt"), "SPECTRAL_NMx refused naming it: %s", err.msg);
	kg_patchset_free(&bad);
}

int main(void)
{
	synthetic();
	argyll_pair("ColorChecker.ti2", "ColorChecker.cht");
	argyll_pair("ColorCheckerSG.ti2", "ColorCheckerSG.cht");
	bundled_layout();
	char dir[] = "/tmp/kg-ids-XXXXXX";
	if (mkdtemp(dir)) {
		xrite_names(dir);
		char cmd[600];
		snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
		if (system(cmd) != 0)
			fprintf(stderr, "note: could not remove %s\n", dir);
	}
	return kg_test_done("calib-patch-ids");
}
