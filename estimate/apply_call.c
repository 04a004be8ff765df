/* Images to files: what the two classifications (kg_classify_rows in apply_classify.c,
 * kg_classify_camera_rows in labels_cam.c) do alike around their own kernels: the
 * default options, the side files' names, the label map with its confidence and mask,
 * the stream into them, the margins and the summary, the preview, and the cleanup that
 * leaves either every file of the call or none. */
#include <stdlib.h>
#include <string.h>

#include "apply_private.h"

void ap_call_begin(classify_call *c, const char *out_hdr, const kg_apply_options **opt,
                   const kg_classify_options **copt, kg_classify_result *res)
{
	memset(c, 0, sizeof(*c));
	if (!*opt) {
		kg_apply_options_init(&c->opt_default);
		*opt = &c->opt_default;
	}
	if (!*copt) {
		kg_classify_options_init(&c->copt_default);
		*copt = &c->copt_default;
	}
	c->paths[0] = out_hdr;
	if (res)
		memset(res, 0, sizeof(*res));
}

int ap_call_paths(classify_call *c, const char *out_hdr, kg_err *err)
{
	int rc;
	if ((rc = kg_apply_side_path(out_hdr, "_confidence.hdr", &c->conf_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, ".json", &c->json_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, ".png", &c->png_path, err)) ||
	    (rc = kg_inputs_check_output(c->json_path, err)) ||
	    (rc = kg_inputs_check_output(c->png_path, err)))
		return rc;
	return 0;
}

int ap_call_open(classify_call *c, const char *out_hdr, int width, int height,
                 const kg_est_material_set *classes, const char *description, int bands,
                 const char *conf_description, const char *const *band_names, kg_err *err)
{
	int rc = ap_open_label_map(out_hdr, width, height, classes, description, &c->ws[0], err);
	if (rc)
		return rc;
	if ((rc = ap_open_floats(c->conf_path, width, height, bands, conf_description,
	                         band_names, &c->ws[1], err)))
		return rc;
	c->paths[1] = c->conf_path;
	if ((rc = ap_open_mask(out_hdr, width, height, &c->mask_path, &c->ws[2], err)))
		return rc;
	c->paths[2] = c->mask_path;
	c->nws = 3;
	return 0;
}

int ap_call_stream(classify_call *c, const kg_est_job *job, int width, int height,
                   kg_est_sink_fn sink, void *user, const feed *in, const char *out_hdr,
                   kg_err *err)
{
	int rc = kg_est_run_stream(job, NULL, width, height, sink, user, &c->local.stats, err);
	if (rc) {
		kg_err_prefix(err, "%s: ", out_hdr);
		return rc;
	}
	if ((rc = ap_check_estimable(&c->local.stats, in, "classify", err)))
		return rc;
	return ap_finish_all(c->ws, c->paths, c->nws, &c->done, err);
}

int ap_call_summary(classify_call *c, const kg_est_kernel *k,
                    const kg_est_material_set *classes, const uint64_t *count,
                    class_stats *cs, const char *out_hdr, int bands, int width, int height,
                    kg_err *err)
{
	int rc = ap_margin_pass(cs, classes->n, out_hdr, c->conf_path, bands, width, height, err);
	if (!rc)
		rc = ap_summarise(k, classes, count, cs, (size_t)width * (size_t)height, &c->local,
		                  err);
	return rc;
}

int ap_call_preview(classify_call *c, const kg_est_material_set *classes,
                    const uint8_t *preview, int pw, int ph, int legend, kg_err *err)
{
	int rc = ap_write_preview(c->png_path, classes, preview, pw, ph, &c->local, legend, err);
	if (!rc)
		ap_written_add(&c->done, c->png_path);
	return rc;
}

void ap_call_cleanup(classify_call *c, int rc, kg_classify_result *res)
{
	for (int i = 0; i < 4; i++)
		if (c->ws[i])
			kg_envi_writer_abort(&c->ws[i]);
	ap_written_clear(&c->done, rc != 0);
	if (rc == 0 && res)
		*res = c->local;
	else
		kg_classify_result_free(&c->local);
	free(c->conf_path);
	free(c->mask_path);
	free(c->json_path);
	free(c->png_path);
}
