/* Fuzz target for the CGATS reader, patch-set extraction and the CSV reader.
 *
 * Run by the shared fuzz driver (fuzz_driver.h) with CGATS words and over-long lines
 * as its mutations; an input the CGATS reader refuses counts as refused.
 *
 * Invariants checked on every input: a refusal always carries a message, a success
 * leaves a consistent table, and everything is freed (the sanitizers see leaks). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cgats.h"
#include "csv.h"
#include "fuzz_driver.h"

static void require(int cond, const char *what)
{
	kg_fuzz_require("fuzz-cgats", cond, what);
}

static void check_refusal(int r, const kg_err *err)
{
	require(r < 0, "return code is 0 or negative");
	require(memchr(err->msg, '\0', sizeof(err->msg)) != NULL, "message is terminated");
	require(err->msg[0] != '\0', "a refusal has a message");
}

static void exercise_table(const kg_cgats_table *t)
{
	require(t->type && t->nfields >= 1 && t->nsets >= 0, "table shape");
	double v;
	for (int s = 0; s < t->nsets; s++)
		for (int f = 0; f < t->nfields; f++) {
			kg_err err = { { 0 } };
			int r = kg_cgats_number(t, s, f, &v, &err);
			if (r != 0)
				check_refusal(r, &err);
		}
	for (int k = 0; k < t->nkeywords; k++) {
		kg_err err = { { 0 } };
		int r = kg_cgats_keyword_number(t, t->keywords[k].name, &v, &err);
		if (r != 0)
			check_refusal(r, &err);
	}
	for (unsigned flags = 0; flags <= KG_RESAMPLE_EXTRAPOLATE; flags++) {
		kg_err err = { { 0 } };
		kg_patchset *ps = NULL;
		int r = kg_patchset_from_table(t, flags, &ps, &err);
		if (r != 0) {
			check_refusal(r, &err);
			require(ps == NULL, "no patch set on failure");
			continue;
		}
		require(ps->n == t->nsets, "one patch per set");
		unsigned fields = (ps->spectra ? KG_PATCH_SPECTRA : 0) | (ps->rgb ? KG_PATCH_RGB : 0) |
		                  (ps->xyz ? KG_PATCH_XYZ : 0) | (ps->lab ? KG_PATCH_LAB : 0) |
		                  (ps->nextra ? KG_PATCH_EXTRA : 0);
		kg_cgats *out = NULL;
		r = kg_patchset_to_cgats(ps, fields, NULL, &out, &err);
		if (r != 0)
			check_refusal(r, &err);
		kg_cgats_free(&out);
		kg_patchset_free(&ps);
	}
}

static int fuzz_cgats_run(const uint8_t *data, size_t size)
{
	kg_err err = { { 0 } };
	kg_cgats *cg = NULL;
	int r = kg_cgats_parse((const char *)data, size, "fuzz.cgats", &cg, &err);
	int refused = r != 0;
	if (r != 0) {
		check_refusal(r, &err);
		require(cg == NULL, "no result on failure");
	} else {
		require(cg->ntables >= 1, "a parsed file has a table");
		for (int k = 0; k < cg->ntables; k++)
			exercise_table(cg->tables[k]);
		kg_cgats_free(&cg);
	}

	kg_csv *csv = NULL;
	kg_err cerr = { { 0 } };
	r = kg_csv_parse((const char *)data, size, "fuzz.csv", &csv, &cerr);
	if (r != 0)
		check_refusal(r, &cerr);
	else {
		double v;
		for (int i = 0; i < csv->nrows; i++)
			for (int c = 0; c < csv->ncols; c++)
				if ((r = kg_csv_number(csv, i, c, &v, &cerr)) != 0)
					check_refusal(r, &cerr);
	}
	kg_csv_free(&csv);
	return refused;
}

static const char *const words[] = {
	"\n", "\"", "\t", " ", "#", "0", "-1", "1e999", "nan", "inf", "0x1p3", "1.5",
	"\nEND_DATA\n", "\nBEGIN_DATA\n", "\nBEGIN_DATA_FORMAT\n", "END_DATA_FORMAT",
	"\nNUMBER_OF_FIELDS 2\n", "\nNUMBER_OF_SETS 1\n", "\nNUMBER_OF_SETS 99999999999\n",
	"KEYWORD \"X\"\n", "SPEC_400 ", "SPEC_700 ", "SPEC_500000 ", "SAMPLE_ID ", "RGB_R ",
	"XYZ_X ", "LAB_L ", "\nSPECTRAL_NORM \"0\"\n", "\nSPECTRAL_START_NM 400\n",
	"\nCGATS.17\n", "\r\n", "\xff\xfe",
};

static const kg_fuzz_target fuzz_cgats = {
	.name = "fuzz-cgats",
	.run = fuzz_cgats_run,
	.words = words,
	.nwords = sizeof(words) / sizeof(words[0]),
	.structural = "\n\t \"#0-.eE",
	.long_line = KG_CGATS_MAX_LINE,
	.mutations = 3000,
};

KG_FUZZ_TARGET(fuzz_cgats)
