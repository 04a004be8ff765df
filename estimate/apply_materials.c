/* Images to files: the declared materials of a classification, and the names and
 * colours of the labels of a label map. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "apply_private.h"

/* ---- the declared materials ------------------------------------------------------ */

void kg_est_material_set_free(kg_est_material_set **pset)
{
	if (!pset || !*pset)
		return;
	kg_est_material_set *s = *pset;
	free(s->materials);
	free(s->spectra);
	free(s->names);
	free(s->mats);
	free(s);
	*pset = NULL;
}

int kg_est_material_set_new(const kg_material_library *lib, const char *library,
                            const char *const *only, int nonly, double angle_deg,
                            kg_est_material_set **out, kg_err *err)
{
	kg_check_arg(lib && out && nonly >= 0 && (nonly == 0 || only), err);
	if (!library)
		library = "material library";
	if (!(angle_deg >= 0 && angle_deg <= 90))
		return kg_fail(err, KG_EINVAL, "%s: incidence angle %g: expected 0 to 90 degrees",
		               library, angle_deg);
	int n = nonly ? nonly : kg_material_library_count(lib);
	char known[1024];
	kg_material_library_names(lib, known, sizeof(known));
	if (n < 1)
		return kg_fail(err, KG_EINVAL, "%s: no materials to classify among", library);
	if (n > KG_EST_MAX_MATERIALS)
		return kg_fail(err, KG_EINVAL, "%s: %d materials: at most %d fit a label map", library,
		               n, KG_EST_MAX_MATERIALS);
	for (int i = 0; i < nonly; i++) {
		if (!kg_material_library_find(lib, only[i]))
			return kg_fail(err, KG_EINVAL, "%s: no material named '%s'; it has: %s", library,
			               only[i], known);
		for (int j = 0; j < i; j++)
			if (strcmp(only[i], only[j]) == 0)
				return kg_fail(err, KG_EINVAL, "%s: material '%s' is named twice", library,
				               only[i]);
	}
	kg_est_material_set *s = calloc(1, sizeof(*s));
	if (!s)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	s->n = n;
	s->angle_deg = angle_deg;
	s->materials = calloc((size_t)n, sizeof(*s->materials));
	s->spectra = calloc((size_t)n, sizeof(*s->spectra));
	s->names = calloc((size_t)n, sizeof(*s->names));
	s->mats = calloc((size_t)n, sizeof(*s->mats));
	if (!s->materials || !s->spectra || !s->names || !s->mats) {
		kg_est_material_set_free(&s);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	double theta = angle_deg * M_PI / 180.0;
	for (int i = 0; i < n; i++) {
		const kg_material *mat =
			nonly ? kg_material_library_find(lib, only[i]) : kg_material_library_get(lib, i);
		int rc = kg_material_reflectance(mat, theta, &s->spectra[i], err);
		if (rc) {
			kg_err_prefix(err, "%s: material '%s': ", library, mat->name);
			kg_est_material_set_free(&s);
			return rc;
		}
		snprintf(s->names[i], sizeof(s->names[i]), "%s", mat->name);
		s->mats[i] = mat;
		s->materials[i].name = s->names[i];
		s->materials[i].spectrum = s->spectra[i].v;
	}
	*out = s;
	return 0;
}

/* ---- classify -------------------------------------------------------------------- */

void kg_classify_result_free(kg_classify_result *r)
{
	if (!r)
		return;
	free(r->classes);
	memset(r, 0, sizeof(*r));
}

/* Distinct colours for the classes: K. L. Kelly's (1965) colours of maximum
 * contrast without white, black and grey (grey marks flagged pixels), then hues
 * spaced by the golden angle. */
void ap_class_colour(int j, unsigned char rgb[3])
{
	/* Kelly's 22 colours of maximum contrast less white, black and grey, ordered so
	 * that every leading run keeps its colours apart (greedy: each next colour the
	 * farthest in CIELAB from those before it and from the flagged grey, the unknown
	 * magenta and the background's near-black; the least distance of the first 10 is
	 * 34 Delta E*ab, of all 19 is 15) */
	static const unsigned char kelly[19][3] = {
		{0xF3, 0xC3, 0x00}, {0xBE, 0x00, 0x32}, {0x60, 0x4E, 0x97}, {0x00, 0x88, 0x56},
		{0xF9, 0x93, 0x79}, {0x8D, 0xB6, 0x00}, {0xF3, 0x84, 0x00}, {0xA1, 0xCA, 0xF1},
		{0x65, 0x45, 0x22}, {0xB3, 0x44, 0x6C}, {0xC2, 0xB2, 0x80}, {0x88, 0x2D, 0x17},
		{0xE6, 0x8F, 0xAC}, {0x00, 0x67, 0xA5}, {0xE2, 0x58, 0x22}, {0x2B, 0x3D, 0x26},
		{0xF6, 0xA6, 0x00}, {0xDC, 0xD3, 0x00}, {0x87, 0x56, 0x92},
	};
	if (j < 19) {
		memcpy(rgb, kelly[j], 3);
		return;
	}
	double h = fmod(j * 0.618033988749895, 1.0) * 6.0, v = j % 2 ? 0.75 : 0.95, s = 0.8;
	int i = (int)h;
	double f = h - i, p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
	double c[6][3] = {{v, t, p}, {q, v, p}, {p, v, t}, {p, q, v}, {t, p, v}, {v, p, q}};
	for (int k = 0; k < 3; k++)
		rgb[k] = (unsigned char)lround(255.0 * c[i % 6][k]);
}

static const unsigned char flagged_grey[3] = {128, 128, 128};
static const unsigned char unknown_magenta[3] = {255, 0, 255};
static const unsigned char background_dark[3] = {24, 24, 24};

/* Labels of the two refusal classes after the n materials. */
int ap_label_unknown(const kg_est_material_set *set) { return set->n + 1; }
int ap_label_background(const kg_est_material_set *set) { return set->n + 2; }

const char *ap_label_name(const kg_est_material_set *set, int label)
{
	if (label == KG_EST_LABEL_NONE)
		return "unclassified";
	if (label == ap_label_unknown(set))
		return "unknown";
	if (label == ap_label_background(set))
		return "background";
	return set->names[label - 1];
}

void ap_label_colour(const kg_est_material_set *set, int label, unsigned char rgb[3])
{
	if (label == KG_EST_LABEL_NONE)
		memcpy(rgb, flagged_grey, 3);
	else if (label == ap_label_unknown(set))
		memcpy(rgb, unknown_magenta, 3);
	else if (label == ap_label_background(set))
		memcpy(rgb, background_dark, 3);
	else
		ap_class_colour(label - 1, rgb);
}
