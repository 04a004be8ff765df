/* Images to files: a kernel's output streamed into ENVI cubes, masks and label maps
 * (the declarations and the list of files are at the end of kg_estimate.h).
 *
 * The cube never exists in memory: kg_est_run_stream hands finished row blocks, in
 * row order, to a sink that passes them to the ENVI writers. Every file goes to a
 * temporary name first; the final names appear only once all of a call's files are
 * complete, and a failure after that point removes the ones already renamed. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "apply_private.h"

/* ---- estimate ---------------------------------------------------------------------- */

typedef struct est_sink {
	kg_envi_writer *cube, *mask;
	staging stage;
	progress prog;
	const feed *in;
	const kg_apply_options *opt;
} est_sink;

static int est_sink_fn(void *user, const kg_est_block *b, kg_err *err)
{
	est_sink *s = user;
	size_t n = (size_t)b->rows * b->width * b->bands;
	int rc;
	if (s->opt->observe) {
		planes pl = ap_feed_planes(s->in, b->input, (size_t)b->rows * b->width);
		if ((rc = s->opt->observe(s->opt->observe_user, b, pl.raw, err)))
			return rc;
	}
	switch (b->format) {
	case KG_EST_F32_BSQ:
		rc = kg_envi_writer_put(s->cube, b->y0, b->y0 + b->rows, KG_LAYOUT_PLANAR, b->data, err);
		break;
	case KG_EST_F32_BIP:
	case KG_EST_WEIGHTS:
		rc = kg_envi_writer_put(s->cube, b->y0, b->y0 + b->rows, KG_LAYOUT_BIP, b->data, err);
		break;
	default: { /* f16: the bit patterns, as exact integers */
		float *v = ap_staging_get(&s->stage, n, err);
		if (!v)
			return KG_ENOMEM;
		const uint16_t *h = b->data;
		for (size_t i = 0; i < n; i++)
			v[i] = h[i];
		rc = kg_envi_writer_put(s->cube, b->y0, b->y0 + b->rows,
		                        b->format == KG_EST_F16_BSQ ? KG_LAYOUT_PLANAR : KG_LAYOUT_BIP,
		                        v, err);
	}
	}
	if (!rc)
		rc = ap_put_bytes(s->mask, &s->stage, b, b->mask, err);
	ap_progress_rows(&s->prog, b->y0 + b->rows);
	return rc;
}

int kg_est_kernel_basis(const kg_est_kernel *k, double *basis, double *mean, kg_err *err)
{
	kg_check_arg(k && basis && mean, err);
	if (!k->k || !k->basis)
		return kg_fail(err, KG_EINVAL, "kernel: it has no basis (a pca kernel has one)");
	memcpy(basis, k->basis, sizeof(double) * KG_NBANDS * k->k);
	for (int l = 0; l < KG_NBANDS; l++)
		mean[l] = k->mean ? k->mean[l] : 0.0;
	return 0;
}

static int basis_keys(const kg_est_kernel *k, kg_envi_pair *extra, char **owned, kg_err *err)
{
	int K = kg_est_kernel_k(k);
	double *basis = malloc(sizeof(double) * KG_NBANDS * K);
	double mean[KG_NBANDS], wl[KG_NBANDS];
	if (!basis)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	int rc = kg_est_kernel_basis(k, basis, mean, err);
	for (int l = 0; l < KG_NBANDS; l++)
		wl[l] = kg_band_nm(l);
	if (!rc)
		rc = kg_envi_format_list(basis, KG_NBANDS * K, &owned[0], err);
	if (!rc)
		rc = kg_envi_format_list(mean, KG_NBANDS, &owned[1], err);
	if (!rc)
		rc = kg_envi_format_list(wl, KG_NBANDS, &owned[2], err);
	free(basis);
	if (rc)
		return rc;
	extra[0] = (kg_envi_pair){"kogei basis", owned[0]};
	extra[1] = (kg_envi_pair){"kogei mean", owned[1]};
	extra[2] = (kg_envi_pair){"kogei basis wavelength", owned[2]};
	return 0;
}

static const char *format_name(kg_est_format f)
{
	switch (f) {
	case KG_EST_F32_BSQ:
	case KG_EST_F32_BIP: return "f32";
	case KG_EST_F16_BSQ:
	case KG_EST_F16_BIP: return "f16";
	case KG_EST_WEIGHTS: return "weights";
	default: return "labels";
	}
}

int kg_estimate_image(const kg_est_kernel *k, const kg_image *img, kg_est_format format,
                      const kg_apply_options *opt, const char *out_hdr, kg_est_stats *stats,
                      kg_err *err)
{
	kg_check_arg(k && img && out_hdr, err);
	int rc = ap_check_image(img, "estimate", err);
	if (rc)
		return rc;
	kg_row_source src;
	kg_row_source_of_image(img, &src);
	return kg_estimate_rows(k, &src, format, opt, out_hdr, stats, err);
}

int kg_estimate_rows(const kg_est_kernel *k, const kg_row_source *src, kg_est_format format,
                     const kg_apply_options *opt, const char *out_hdr, kg_est_stats *stats,
                     kg_err *err)
{
	kg_check_arg(k && src && out_hdr, err);
	kg_apply_options dflt;
	if (!opt) {
		kg_apply_options_init(&dflt);
		opt = &dflt;
	}
	if (format != KG_EST_F32_BSQ && format != KG_EST_F32_BIP && format != KG_EST_F16_BSQ &&
	    format != KG_EST_F16_BIP && format != KG_EST_WEIGHTS)
		return kg_fail(err, KG_EINVAL, "%s: output format %d: expected f32, f16 or weights",
		               out_hdr, (int)format);
	int K = kg_est_kernel_k(k);
	if (format == KG_EST_WEIGHTS && K == 0)
		return kg_fail(err, KG_EINVAL,
		               "%s: weights output needs a method with a K-dimensional basis (pca); "
		               "this kernel gives spectra only",
		               out_hdr);

	feed in;
	int rc = ap_feed_init(&in, src, opt, "estimate", err);
	if (rc)
		return rc;
	kg_est_stats local;
	if (!stats)
		stats = &local;

	char *owned[3] = {NULL, NULL, NULL};
	char *mask_path = NULL;
	kg_envi_writer *ws[2] = {NULL, NULL};
	const char *paths[2] = {out_hdr, NULL};
	est_sink sink = {0};
	written done = {0};
	double wl[KG_NBANDS];
	const char *band_names[KG_EST_MAX_K];
	char band_text[KG_EST_MAX_K][16];
	kg_envi_pair extra[4];
	kg_envi_meta m = ap_envi_meta(
		src->width, src->height, kg_est_format_bands(k, format),
		(format == KG_EST_F16_BSQ || format == KG_EST_F16_BIP) ? KG_ENVI_U16 : KG_ENVI_F32,
		(format == KG_EST_F32_BSQ || format == KG_EST_F16_BSQ) ? KG_ENVI_BSQ : KG_ENVI_BIP,
		opt->description);
	m.extra = extra;
	if (format == KG_EST_WEIGHTS) {
		if ((rc = basis_keys(k, extra, owned, err)))
			goto out;
		m.n_extra = 3;
		for (int i = 0; i < K; i++) {
			snprintf(band_text[i], sizeof(band_text[i]), "w%d", i + 1);
			band_names[i] = band_text[i];
		}
		m.band_names = band_names;
	} else {
		for (int l = 0; l < KG_NBANDS; l++)
			wl[l] = kg_band_nm(l);
		m.wavelength = wl;
	}
	if (m.data_type == KG_ENVI_U16)
		extra[m.n_extra++] = (kg_envi_pair){"kogei sample format", "ieee-half"};

	if ((rc = kg_envi_writer_open(out_hdr, &m, &ws[0], err)))
		goto out;
	if ((rc = ap_open_mask(out_hdr, src->width, src->height, &mask_path, &ws[1], err)))
		goto out;
	paths[1] = mask_path;

	kg_est_job job;
	kg_est_job_init(&job, k, format);
	ap_feed_job(&in, &job);
	job.threads = opt->threads;
	job.block_rows = opt->block_rows;
	job.isa = opt->isa;
	sink.cube = ws[0];
	sink.mask = ws[1];
	sink.in = &in;
	sink.opt = opt;
	ap_progress_init(&sink.prog, opt, "estimate", src->width, src->height);
	rc = kg_est_run_stream(&job, NULL, src->width, src->height, est_sink_fn, &sink, stats,
	                       err);
	if (rc) {
		kg_err_prefix(err, "%s (%s): ", out_hdr, format_name(format));
		goto out;
	}
	if ((rc = ap_check_estimable(stats, &in, "estimate", err)))
		goto out;
	rc = ap_finish_all(ws, paths, 2, &done, err);

out:
	for (int i = 0; i < 2; i++)
		if (ws[i])
			kg_envi_writer_abort(&ws[i]);
	ap_written_clear(&done, rc != 0);
	free(sink.stage.v);
	free(mask_path);
	for (int i = 0; i < 3; i++)
		free(owned[i]);
	return rc;
}
