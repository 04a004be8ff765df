/* Images to files: the files of a call (temporary names, renamed once all are
 * complete, removed again on a later failure), the staging of bytes and the ENVI
 * writers of cubes, masks and label maps. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "apply_private.h"

/* ---- files written by a call ----------------------------------------------------- */

/* Final names of files already in place, removed again if a later step fails. */
void ap_written_add(written *w, const char *path)
{
	if (w->n < 16)
		w->paths[w->n++] = strdup(path);
}

void ap_written_add_envi(written *w, const char *path)
{
	char *hdr = NULL, *data = NULL;
	if (kg_envi_paths(path, &hdr, &data, NULL) == 0) {
		ap_written_add(w, data);
		ap_written_add(w, hdr);
	}
	free(hdr);
	free(data);
}

void ap_written_clear(written *w, int remove)
{
	for (int i = 0; i < w->n; i++) {
		if (remove && w->paths[i])
			unlink(w->paths[i]);
		free(w->paths[i]);
	}
	w->n = 0;
}

/* Finish the writers in order; any failure removes what was finished before. */
int ap_finish_all(kg_envi_writer **ws, const char *const *paths, int n, written *done,
                      kg_err *err)
{
	int rc = 0;
	for (int i = 0; i < n; i++) {
		if (rc) {
			kg_envi_writer_abort(&ws[i]);
			continue;
		}
		rc = kg_envi_writer_finish(&ws[i], err);
		if (rc)
			kg_err_prefix(err, "%s: ", paths[i]);
		else
			ap_written_add_envi(done, paths[i]);
	}
	return rc;
}

/* A float staging buffer for blocks that are not float32 (f16 bits, masks, labels);
 * the ENVI writer converts the values (exact integers) to the file's type. */
float *ap_staging_get(staging *s, size_t n, kg_err *err)
{
	if (n > s->cap) {
		float *v = realloc(s->v, n * sizeof(float));
		if (!v) {
			kg_fail(err, KG_ENOMEM, "out of memory for a block of %zu values", n);
			return NULL;
		}
		s->v = v;
		s->cap = n;
	}
	return s->v;
}

int ap_put_bytes(kg_envi_writer *w, staging *s, const kg_est_block *b, const uint8_t *src,
                     kg_err *err)
{
	size_t n = (size_t)b->rows * b->width;
	float *v = ap_staging_get(s, n, err);
	if (!v)
		return KG_ENOMEM;
	for (size_t i = 0; i < n; i++)
		v[i] = src[i];
	return kg_envi_writer_put(w, b->y0, b->y0 + b->rows, KG_LAYOUT_BIP, v, err);
}

kg_envi_meta ap_envi_meta(int width, int height, int bands, enum kg_envi_type type,
                          enum kg_envi_interleave interleave, const char *description)
{
	kg_envi_meta m = {0};
	m.samples = width;
	m.lines = height;
	m.bands = bands;
	m.data_type = type;
	m.interleave = interleave;
	m.description = description;
	return m;
}

static const char mask_description[] =
	"kogei pixel flags (bits): 1 = an input channel is NaN or Inf; 2 = clipped: a "
	"channel >= the clip level; 4 = negative reflectance clamped to 0. A pixel with "
	"bit 1 or 2 set was not estimated (NaN in the cube; unclassified in a label map)";

int ap_open_mask(const char *out_hdr, int width, int height, char **mask_path,
                     kg_envi_writer **w, kg_err *err)
{
	int rc = kg_apply_side_path(out_hdr, "_mask.hdr", mask_path, err);
	if (rc)
		return rc;
	kg_envi_meta m =
		ap_envi_meta(width, height, 1, KG_ENVI_U8, KG_ENVI_BSQ, mask_description);
	return kg_envi_writer_open(*mask_path, &m, w, err); /* its messages name the file */
}

int ap_open_floats(const char *path, int width, int height, int bands,
                   const char *description, const char *const *band_names,
                   kg_envi_writer **w, kg_err *err)
{
	kg_envi_meta m =
		ap_envi_meta(width, height, bands, KG_ENVI_F32, KG_ENVI_BIP, description);
	m.band_names = band_names;
	return kg_envi_writer_open(path, &m, w, err);
}

int ap_open_label_map(const char *path, int width, int height,
                      const kg_est_material_set *classes, const char *description,
                      kg_envi_writer **w, kg_err *err)
{
	const int nlabels = classes->n + 3;
	const char **names = calloc((size_t)nlabels, sizeof(char *));
	unsigned char *lookup = malloc(3 * (size_t)nlabels);
	int rc = names && lookup ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
	for (int l = 0; !rc && l < nlabels; l++) {
		names[l] = ap_label_name(classes, l);
		ap_label_colour(classes, l, lookup + 3 * l);
	}
	if (!rc) {
		kg_envi_meta m =
			ap_envi_meta(width, height, 1, KG_ENVI_U8, KG_ENVI_BSQ, description);
		m.classes = nlabels;
		m.class_names = names;
		m.class_lookup = lookup;
		rc = kg_envi_writer_open(path, &m, w, err);
	}
	free(names);
	free(lookup);
	return rc;
}
