/* Images to files: classification of an image into a label map, its margins, mask,
 * LABELS.json and preview. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "apply_private.h"

typedef struct cls_sink {
	kg_envi_writer *labels, *conf, *mask;
	staging stage;
	progress prog;
	const feed *in;
	const refusal *refuse;
	int nmaterials;
	uint64_t count[KG_EST_MAX_MATERIALS + 3]; /* per label */
	class_stats *cs;   /* per material, index label - 1 */
	uint8_t *preview;  /* pw x ph labels, nearest sample */
	int pw, ph, next_py;
	int height;
} cls_sink;

static int cls_sink_fn(void *user, const kg_est_block *b, kg_err *err)
{
	cls_sink *s = user;
	size_t n = (size_t)b->rows * b->width;
	uint8_t *lab = (uint8_t *)b->data;
	float *conf = (float *)b->confidence;
	planes pl = ap_feed_planes(s->in, b->input, n);
	for (size_t i = 0; i < n; i++) {
		ap_refuse_pixel(s->refuse, &pl, i, &lab[i], &conf[i]);
		s->count[lab[i]]++;
		if (lab[i] == KG_EST_LABEL_NONE || lab[i] > s->nmaterials)
			continue;
		int bad = ap_class_stats_add(&s->cs[lab[i] - 1], conf[i], pl.kin + 3 * i, err);
		if (bad)
			return bad;
	}
	ap_preview_rows(s->preview, s->pw, s->ph, &s->next_py, s->height, b, lab);
	int rc = ap_put_bytes(s->labels, &s->stage, b, lab, err);
	if (!rc)
		rc = kg_envi_writer_put(s->conf, b->y0, b->y0 + b->rows, KG_LAYOUT_BIP, conf, err);
	if (!rc)
		rc = ap_put_bytes(s->mask, &s->stage, b, b->mask, err);
	ap_progress_rows(&s->prog, b->y0 + b->rows);
	return rc;
}

static void cls_sink_free(cls_sink *s)
{
	ap_class_stats_free(s->cs, s->nmaterials);
	free(s->preview);
	free(s->stage.v);
}

void kg_classify_options_init(kg_classify_options *o)
{
	memset(o, 0, sizeof(*o));
	o->distance = KG_EST_DIST_PLAIN;
	o->frames = 1;
	o->noise_relative = 0.01;
	o->noise_floor = 0.002;
	o->residual_relative = 0.0;
	o->unknown_threshold = 0.0;
	o->background_level = 0.01;
}

static const char *side_name_variance(const kg_classify_info *info)
{
	return info && info->variance ? info->variance : "the variance image";
}

static const char *side_name_mask(const kg_classify_info *info)
{
	return info && info->mask ? info->mask : "the mask";
}

int ap_check_options(const kg_classify_options *o, const kg_row_source *img,
                         const kg_classify_info *info, const char *what, kg_err *err)
{
	if (o->frames < 1)
		return kg_fail(err, KG_EINVAL, "%s: frames %d: expected 1 or more", what, o->frames);
	const double nonneg[3] = {o->noise_relative, o->noise_floor, o->residual_relative};
	const char *names[3] = {"noise_relative", "noise_floor", "residual_relative"};
	for (int i = 0; i < 3; i++)
		if (!(nonneg[i] >= 0 && isfinite(nonneg[i])))
			return kg_fail(err, KG_EINVAL, "%s: %s %g: expected a finite value >= 0", what,
			               names[i], nonneg[i]);
	if (!(o->unknown_threshold >= 0))
		return kg_fail(err, KG_EINVAL,
		               "%s: unknown threshold %g: expected a value > 0, 0 for the 99.9 %% "
		               "point or infinity for no unknown test",
		               what, o->unknown_threshold);
	if (!(o->background_level >= 0 && o->background_level <= 1))
		return kg_fail(err, KG_EINVAL,
		               "%s: background level %g: expected 0 to 1 of full scale (0: none)", what,
		               o->background_level);
	if (o->distance != KG_EST_DIST_PLAIN && o->distance != KG_EST_DIST_SCALE_FREE)
		return kg_fail(err, KG_EINVAL, "%s: distance %d: expected plain or scale-free", what,
		               (int)o->distance);
	const kg_row_source *side[2] = {o->variance, o->mask};
	const int side_channels[2] = {3, 1};
	for (int s = 0; s < 2; s++) {
		const kg_row_source *v = side[s];
		if (!v)
			continue;
		const char *name = s ? side_name_mask(info) : side_name_variance(info);
		if (!v->read || v->width != img->width || v->height != img->height)
			return kg_fail(err, KG_EINVAL,
			               "%s: %s is %d x %d pixels: expected the image's size, %d x %d",
			               what, name, v->width, v->height, img->width, img->height);
		if (v->channels != side_channels[s])
			return kg_fail(err, KG_EINVAL, "%s: %s has %d channel%s: expected %d (%s)", what,
			               name, v->channels, v->channels == 1 ? "" : "s", side_channels[s],
			               s ? "grey: 0 = background, non-zero = object"
			                 : "one variance per channel of the image");
	}
	return 0;
}

int kg_classify_image(const kg_est_kernel *k, const kg_est_material_set *set,
                      kg_est_distance distance, const kg_image *img,
                      const kg_apply_options *opt, const kg_classify_info *info,
                      const char *out_hdr, kg_classify_result *res, kg_err *err)
{
	kg_classify_options o;
	kg_classify_options_init(&o);
	o.distance = distance;
	o.unknown_threshold = INFINITY;
	o.background_level = 0;
	return kg_classify_image_opts(k, set, img, opt, &o, info, out_hdr, res, err);
}

int kg_classify_image_opts(const kg_est_kernel *k, const kg_est_material_set *set,
                           const kg_image *img, const kg_apply_options *opt,
                           const kg_classify_options *copt, const kg_classify_info *info,
                           const char *out_hdr, kg_classify_result *res, kg_err *err)
{
	kg_check_arg(k && set && img && out_hdr, err);
	if (res)
		memset(res, 0, sizeof(*res));
	int rc = ap_check_image(img, "classify", err);
	if (rc)
		return rc;
	kg_row_source src;
	kg_row_source_of_image(img, &src);
	return kg_classify_rows(k, set, &src, opt, copt, info, out_hdr, res, err);
}

int kg_classify_rows(const kg_est_kernel *k, const kg_est_material_set *set,
                     const kg_row_source *src, const kg_apply_options *opt,
                     const kg_classify_options *copt, const kg_classify_info *info,
                     const char *out_hdr, kg_classify_result *res, kg_err *err)
{
	kg_check_arg(k && set && src && out_hdr, err);
	classify_call call;
	ap_call_begin(&call, out_hdr, &opt, &copt, res);
	const kg_est_distance distance = copt->distance;
	if (kg_est_kernel_k(k) == 0)
		return kg_fail(err, KG_EINVAL,
		               "%s: classification works in the K-dimensional subspace of a basis "
		               "(the paper's eq. 11): it needs a method with one (pca)",
		               out_hdr);
	if (set->n < 1 || set->n > KG_EST_MAX_MATERIALS)
		return kg_fail(err, KG_EINVAL, "%s: %d materials: expected 1 to %d", out_hdr, set->n,
		               KG_EST_MAX_MATERIALS);

	feed in;
	int rc = ap_feed_init(&in, src, opt, "classify", err);
	if (!rc)
		rc = ap_check_options(copt, src, info, "classify", err);
	if (rc)
		return rc;
	in.var = copt->variance;
	in.var_name = side_name_variance(info);
	in.mask = copt->mask;
	refusal refuse;
	kg_est_classifier *cls = NULL;
	cls_sink sink = {0};
	const int W = src->width, H = src->height;

	if ((rc = kg_est_classifier_new(k, set->materials, set->n, distance, &cls, err)) ||
	    (rc = ap_refusal_init(&refuse, k, cls, set, opt, copt, &call.local, err)) ||
	    (rc = ap_call_paths(&call, out_hdr, err)))
		goto out;
	ap_preview_size(W, H, &sink.pw, &sink.ph);
	sink.preview = malloc((size_t)sink.pw * sink.ph);
	sink.cs = calloc((size_t)set->n, sizeof(*sink.cs));
	if (!sink.preview || !sink.cs) {
		rc = kg_fail(err, KG_ENOMEM, "classify: out of memory");
		goto out;
	}
	char desc[160];
	snprintf(desc, sizeof(desc), "kogei classify: %d materials, %s distance, %g degrees",
	         set->n, ap_distance_name(distance), set->angle_deg);
	const char *band[1] = {"margin"};
	if ((rc = ap_call_open(&call, out_hdr, W, H, set,
	                       opt->description ? opt->description : desc, 1,
	                       "kogei classify confidence: distance to the runner-up minus "
	                       "distance to the chosen material; NaN for flagged, unknown and "
	                       "background pixels, Inf with one material",
	                       band, err)))
		goto out;

	kg_est_job job;
	kg_est_job_init(&job, k, KG_EST_LABELS);
	ap_feed_job(&in, &job);
	job.classifier = cls;
	job.threads = opt->threads;
	job.block_rows = opt->block_rows;
	job.isa = opt->isa;
	sink.labels = call.ws[0];
	sink.conf = call.ws[1];
	sink.mask = call.ws[2];
	sink.in = &in;
	sink.refuse = &refuse;
	sink.nmaterials = set->n;
	sink.height = H;
	ap_progress_init(&sink.prog, opt, "classify", W, H);
	if ((rc = ap_call_stream(&call, &job, W, H, cls_sink_fn, &sink, &in, out_hdr, err)) ||
	    (rc = ap_call_summary(&call, k, set, sink.count, sink.cs, out_hdr, 1, W, H, err)))
		goto out;
	const char *files[4] = {out_hdr, call.conf_path, call.mask_path, call.png_path};
	if ((rc = ap_write_labels_json(call.json_path, set, copt, src, opt, info, files,
	                               &call.local, err)))
		goto out;
	ap_written_add(&call.done, call.json_path);
	rc = ap_call_preview(&call, set, sink.preview, sink.pw, sink.ph, !copt->preview_no_legend,
	                     err);

out:
	ap_call_cleanup(&call, rc, res);
	kg_est_classifier_free(&cls);
	cls_sink_free(&sink);
	return rc;
}
