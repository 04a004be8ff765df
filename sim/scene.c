/* Scene layout and rendering: a grid of square tiles (chart patches, then material
 * samples on a new row) on a flat background, each pixel read through the noise
 * model. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_sim.h"

/* Large enough for any chart and library, small enough that width*height*61 floats
 * of truth cube stay addressable. */
#define MAX_SIDE 32768

static char **names_dup(const char *const *names, int n, const char *fallback_prefix)
{
	char **out = calloc((size_t)(n > 0 ? n : 1), sizeof(*out));
	if (!out)
		return NULL;
	for (int i = 0; i < n; i++) {
		if (names && names[i]) {
			out[i] = strdup(names[i]);
		} else {
			size_t len = strlen(fallback_prefix) + 16;
			out[i] = malloc(len);
			if (out[i])
				snprintf(out[i], len, "%s%d", fallback_prefix, i + 1);
		}
		if (!out[i]) {
			for (int j = 0; j < i; j++)
				free(out[j]);
			free(out);
			return NULL;
		}
	}
	return out;
}

static void names_free(char **names, int n)
{
	if (!names)
		return;
	for (int i = 0; i < n; i++)
		free(names[i]);
	free(names);
}

void kg_sim_scene_free(kg_sim_scene **ps)
{
	if (!ps || !*ps)
		return;
	kg_sim_scene *s = *ps;
	free(s->truth);
	names_free(s->sample_names, s->nsamples);
	free(s->sample_class);
	names_free(s->class_names, s->nclasses);
	free(s->sample);
	free(s->label);
	free(s->rgb);
	free(s);
	*ps = NULL;
}

/* Tile position of sample i: patches fill rows from the top, materials start on
 * the row after the last patch row. */
static void tile_of(const kg_sim_scene_desc *d, int i, int *row, int *col)
{
	int patch_rows = (d->npatches + d->columns - 1) / d->columns;
	if (i < d->npatches) {
		*row = i / d->columns;
		*col = i % d->columns;
	} else {
		int j = i - d->npatches;
		*row = patch_rows + j / d->columns;
		*col = j % d->columns;
	}
}

static int check_desc(const kg_sim_scene_desc *d, kg_err *err)
{
	if (d->npatches < 0 || d->nmaterials < 0 || d->npatches + d->nmaterials < 1)
		return kg_fail(err, KG_EINVAL,
		               "scene: expected at least one chart patch or material sample");
	if ((d->npatches && !d->patches) || (d->nmaterials && !d->materials))
		return kg_fail(err, KG_EINVAL, "scene: spectra missing");
	if (d->tile < 1 || d->tile > 4096)
		return kg_fail(err, KG_EINVAL, "scene: tile size %d: expected 1 to 4096 pixels",
		               d->tile);
	if (d->gap < 0 || d->gap > 4096)
		return kg_fail(err, KG_EINVAL, "scene: gap %d: expected 0 to 4096 pixels", d->gap);
	if (d->columns < 1 || d->columns > 1024)
		return kg_fail(err, KG_EINVAL, "scene: columns %d: expected 1 to 1024", d->columns);
	if (d->nmaterials > 65000)
		return kg_fail(err, KG_EINVAL, "scene: %d materials: at most 65000 classes",
		               d->nmaterials);
	if (!isfinite(d->background))
		return kg_fail(err, KG_EINVAL, "scene: background reflectance is not finite");
	for (int i = 0; i < d->npatches; i++)
		if (!kg_spectrum_isfinite(&d->patches[i]))
			return kg_fail(err, KG_EINVAL, "scene: patch %s: spectrum is not finite",
			               d->patch_names ? d->patch_names[i] : "?");
	for (int i = 0; i < d->nmaterials; i++)
		if (!kg_spectrum_isfinite(&d->materials[i]))
			return kg_fail(err, KG_EINVAL, "scene: material %s: spectrum is not finite",
			               d->material_names ? d->material_names[i] : "?");
	return 0;
}

int kg_sim_scene_new(const kg_sim_scene_desc *d, const kg_sim_capture *c, uint64_t seed,
                     kg_sim_scene **out, kg_err *err)
{
	kg_check_arg(d && c && out, err);
	*out = NULL;
	int ret = check_desc(d, err);
	if (ret)
		return ret;
	int patch_rows = (d->npatches + d->columns - 1) / d->columns;
	int material_rows = (d->nmaterials + d->columns - 1) / d->columns;
	int rows = patch_rows + material_rows;
	int cols = d->npatches + d->nmaterials < d->columns ? d->npatches + d->nmaterials
	                                                    : d->columns;
	long long width = (long long)cols * (d->tile + d->gap) + d->gap;
	long long height = (long long)rows * (d->tile + d->gap) + d->gap;
	if ((d->width > 0 && d->width < width) || (d->height > 0 && d->height < height))
		return kg_fail(err, KG_ERANGE, "scene: %d x %d pixels cannot hold the %lld x %lld "
		               "grid of tiles", d->width, d->height, width, height);
	int ox = d->width > 0 ? (int)(d->width - width) / 2 : 0;
	int oy = d->height > 0 ? (int)(d->height - height) / 2 : 0;
	if (d->width > 0)
		width = d->width;
	if (d->height > 0)
		height = d->height;
	if (width > MAX_SIDE || height > MAX_SIDE)
		return kg_fail(err, KG_ERANGE,
		               "scene: %lld x %lld pixels: expected at most %d on a side "
		               "(use a smaller tile size or more columns)",
		               width, height, MAX_SIDE);

	kg_sim_scene *s = calloc(1, sizeof(*s));
	if (!s)
		return kg_fail(err, KG_ENOMEM, "scene: out of memory");
	s->width = (int)width;
	s->height = (int)height;
	s->nsamples = d->npatches + d->nmaterials;
	s->nclasses = 1 + d->nmaterials + (d->npatches > 0);
	size_t npix = (size_t)s->width * (size_t)s->height;
	s->truth = malloc((size_t)s->nsamples * sizeof(*s->truth));
	s->sample_class = malloc((size_t)s->nsamples * sizeof(*s->sample_class));
	s->sample_names = calloc((size_t)s->nsamples, sizeof(*s->sample_names));
	s->class_names = calloc((size_t)s->nclasses, sizeof(*s->class_names));
	s->sample = malloc(npix * sizeof(*s->sample));
	s->label = malloc(npix * sizeof(*s->label));
	s->rgb = malloc(npix * 3 * sizeof(*s->rgb));
	if (!s->truth || !s->sample_class || !s->sample_names || !s->class_names ||
	    !s->sample || !s->label || !s->rgb)
		goto nomem;

	char **pn = names_dup(d->patch_names, d->npatches, "patch");
	char **mn = names_dup(d->material_names, d->nmaterials, "material");
	if (!pn || !mn) {
		names_free(pn, d->npatches);
		names_free(mn, d->nmaterials);
		goto nomem;
	}
	int chart_class = 1 + d->nmaterials;
	for (int i = 0; i < d->npatches; i++) {
		s->truth[i] = d->patches[i];
		s->sample_names[i] = pn[i];
		s->sample_class[i] = chart_class;
	}
	for (int j = 0; j < d->nmaterials; j++) {
		s->truth[d->npatches + j] = d->materials[j];
		s->sample_names[d->npatches + j] = mn[j];
		s->sample_class[d->npatches + j] = 1 + j;
	}
	free(pn);
	free(mn);
	s->class_names[0] = strdup(KG_SIM_UNCLASSIFIED);
	for (int j = 0; j < d->nmaterials; j++)
		s->class_names[1 + j] = strdup(s->sample_names[d->npatches + j]);
	if (d->npatches > 0)
		s->class_names[chart_class] = strdup(KG_SIM_CHART_CLASS);
	for (int k = 0; k < s->nclasses; k++)
		if (!s->class_names[k])
			goto nomem;

	s->background = kg_spectrum_const(d->background);
	for (size_t p = 0; p < npix; p++) {
		s->sample[p] = -1;
		s->label[p] = 0;
	}
	for (int i = 0; i < s->nsamples; i++) {
		int row, col;
		tile_of(d, i, &row, &col);
		int x0 = ox + d->gap + col * (d->tile + d->gap);
		int y0 = oy + d->gap + row * (d->tile + d->gap);
		for (int y = y0; y < y0 + d->tile; y++)
			for (int x = x0; x < x0 + d->tile; x++) {
				size_t p = (size_t)y * (size_t)s->width + (size_t)x;
				s->sample[p] = i;
				s->label[p] = (uint16_t)s->sample_class[i];
			}
	}

	/* Every pixel is an independent reading of its sample's noise-free value; raster
	 * order fixes the draws. */
	double *mean = malloc((size_t)(s->nsamples + 1) * 3 * sizeof(*mean));
	if (!mean)
		goto nomem;
	for (int i = 0; i < s->nsamples; i++)
		kg_sim_capture_mean(c, &s->truth[i], mean + 3 * (i + 1));
	kg_sim_capture_mean(c, &s->background, mean);
	kg_rng rng;
	kg_rng_seed(&rng, seed);
	for (size_t p = 0; p < npix; p++) {
		const double *m = mean + 3 * (s->sample[p] + 1);
		for (int ch = 0; ch < 3; ch++)
			s->rgb[3 * p + (size_t)ch] = (float)kg_sim_noise_apply(&c->noise, m[ch], &rng);
	}
	free(mean);
	*out = s;
	return 0;
nomem:
	kg_sim_scene_free(&s);
	return kg_fail(err, KG_ENOMEM, "scene: out of memory");
}
