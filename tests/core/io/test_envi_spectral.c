/* Cubes and a classification file written here must read back in Spectral Python
 * (an independent ENVI reader): envi_spectral.py compares values and header fields.
 * Skipped (77) when /usr/bin/python3 or python3-spectral is missing. */
#include <string.h>
#include <sys/wait.h>

#include "io_util.h"
#include "kg_core.h"
#include "kg_test.h"

enum { S = 7, L = 5, B = 4 };

static void write_cube(const char *name, enum kg_envi_interleave il, enum kg_envi_type type)
{
	static const double wl[B] = {400, 405, 410, 415};
	static const char *const names[B] = {"R", "G", "B", "NIR"};
	float planar[B * L * S];
	for (int b = 0; b < B; b++)
		for (int y = 0; y < L; y++)
			for (int x = 0; x < S; x++)
				planar[(b * L + y) * S + x] = (float)(x * 7 + y * 13 + b * 31) / 1000.0f;
	kg_envi_meta m = {.samples = S, .lines = L, .bands = B, .data_type = type, .interleave = il,
	                  .wavelength = wl, .band_names = names,
	                  .scale = type == KG_ENVI_U16 ? 1000 : 0};
	kg_envi_writer *w;
	kg_err err;
	char hdr[64];
	snprintf(hdr, sizeof(hdr), "%s.hdr", name);
	CHECK(kg_envi_writer_open(kg_test_path(hdr), &m, &w, &err) == 0, "%s: %s", name, err.msg);
	/* Two blocks, last first. */
	CHECK(kg_envi_writer_put(w, 3, 5, KG_LAYOUT_PLANAR, NULL, &err) == KG_EINVAL, "NULL data");
	float blk[B * 3 * S];
	for (int part = 1; part >= 0; part--) {
		int y0 = part ? 3 : 0, y1 = part ? 5 : 3;
		for (int b = 0; b < B; b++)
			memcpy(blk + (size_t)b * (y1 - y0) * S, planar + ((size_t)b * L + y0) * S,
			       (size_t)(y1 - y0) * S * sizeof(float));
		CHECK(kg_envi_writer_put(w, y0, y1, KG_LAYOUT_PLANAR, blk, &err) == 0, "put: %s", err.msg);
	}
	CHECK(kg_envi_writer_finish(&w, &err) == 0, "%s: finish: %s", name, err.msg);
}

int main(void)
{
	if (!kg_test_file_exists("/usr/bin/python3"))
		kg_test_skip("/usr/bin/python3 not installed");
	io_tmpdir("spectral");
	write_cube("bsq_f32", KG_ENVI_BSQ, KG_ENVI_F32);
	write_cube("bil_f32", KG_ENVI_BIL, KG_ENVI_F32);
	write_cube("bip_u16", KG_ENVI_BIP, KG_ENVI_U16);
	float labels[6 * 3];
	for (int i = 0; i < 18; i++)
		labels[i] = (float)(i % 3);
	const char *cn[3] = {"unclassified", "gold", "shakudo"};
	unsigned char lut[9] = {0, 0, 0, 255, 200, 0, 40, 30, 60};
	kg_envi_meta m = {.samples = 6, .lines = 3, .bands = 1, .data_type = KG_ENVI_U8,
	                  .classes = 3, .class_names = cn, .class_lookup = lut};
	kg_err err;
	CHECK(kg_envi_write(kg_test_path("labels.hdr"), &m, KG_LAYOUT_BIP, labels, &err) == 0, "labels: %s",
	      err.msg);
	if (kg_test_failures)
		return kg_test_done("envi-spectral");

	const char *root = getenv("KOGEI_SOURCE_ROOT");
	char cmd[8192];
	snprintf(cmd, sizeof(cmd), "/usr/bin/python3 '%s/tests/core/io/envi_spectral.py' '%s'",
	         root && *root ? root : KG_SOURCE_ROOT, kg_test_scratch());
	fflush(stdout);
	int st = system(cmd);
	int code = st != -1 && WIFEXITED(st) ? WEXITSTATUS(st) : -1;
	if (code == 77)
		kg_test_skip("python3-spectral not installed");
	CHECK(code == 0, "Spectral Python disagrees (exit status %d)", code);
	return kg_test_done("envi-spectral");
}
