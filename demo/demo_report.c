/* The demo's report: the cube, the label map and its regions read back from their
 * files and compared with the object's truth (the material and incidence angle of
 * each pixel of the render the photograph was taken of), the object re-rendered from
 * the estimated labels beside its render from the truth, as plots and a short summary.
 *
 * Every number comes from the files the pipeline wrote (cube.hdr, labels.hdr,
 * labels_regions.hdr and .csv) and from the recorded truth, so the report checks the
 * outputs, not the code's memory. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "demo_private.h"
#include "kg_config.h"

/* How one material of the object came out. */
typedef struct material_eval {
	const char *name;
	int region;     /* its region in the scene (d->region_*), -1 if it has none */
	long pixels;    /* judged: object pixels not at a border, at the searched angles */
	long flagged;   /* of them, not estimated (NaN) */
	long correct;   /* labelled with a class that holds this material */
	long mixed;     /* at a border: not judged */
	long grazing, grazing_correct; /* beyond the searched angles: counted apart */
	double tsum[KG_NBANDS];        /* the true reflectance at each pixel's angle */
	double sum[KG_NBANDS], sumsq[KG_NBANDS];
	double rmse_sum, de00_sum;
	double scale_sum, srmse_sum; /* the estimate's best scale onto the truth, and the
	                                RMSE after it */
	double angle_sum;
	kg_spectrum truth;    /* mean true reflectance over the estimated pixels */
	kg_spectrum mean, sd; /* of the estimated spectra */
	double rmse, de00;    /* means over the estimated pixels; dE00 after the scale */
	double scale, srmse;  /* mean best scale, mean RMSE after it */
	double angle;         /* mean incidence */
	/* its region's material in the re-render: the majority class of its judged pixels
	 * among the material classes, a compound resolved by the label map's regions
	 * where they resolved it, else the compound's first member */
	int est_class;        /* -1: no pixel with a material class */
	long est_votes;
	int est_material;     /* library index */
	const char *est_how;
} material_eval;

/* A region of the label map (labels_regions.csv) of DEMO_REGION_MIN_PIXELS or more. */
typedef struct region_eval {
	unsigned id;
	long pixels;
	char cls[KG_EST_CLASS_NAME_MAX], label[KG_EST_CLASS_NAME_MAX];
	double posterior;
	int bits;           /* the materials its label holds */
	long object, searched, grazing;
	long *votes;        /* per truth class */
	int truth;          /* majority material (library index) of its object pixels */
	enum { REGION_JUDGED, REGION_BACKGROUND, REGION_GRAZING } kind;
	int right, exact;   /* label holds the truth; label is the truth alone */
} region_eval;

typedef struct report {
	int n;              /* materials of the library */
	material_eval *m;
	long *confusion;    /* n x (n + 1): true row, predicted column, last = unclassified */
	long pixels, correct, unclassified;
	long mixed;         /* object pixels at a border, mixed by demosaicing: not judged */
	long grazing, grazing_correct; /* beyond the searched angles: counted apart */
	long background;    /* pixels off the object */
	long *background_by_class; /* their labels */
	int width, height;
	float *cube;        /* width * height * 61, BIP */
	float *labels;      /* class per pixel */
	int nclasses;       /* of the label map */
	char **class_names;
	int *class_bits;    /* per class: the materials it holds (bit j: material j) */
	int *class_first;   /* per class: its first member, -1 for none */
	float *table;       /* true reflectance per material and angle step */
	float *regions;     /* region number per pixel */
	unsigned max_region;
	int *region_bits;   /* per region number: the materials its decided label holds */
	region_eval *reg;   /* the regions of DEMO_REGION_MIN_PIXELS or more */
	int nreg;
	int nreg_judged, nreg_right, nreg_exact, nreg_background, nreg_grazing;
	int *estimate_material; /* per scene region: the material the re-render gives it */
	demo_rerender_result rr;
	kg_illuminant *d65;
	kg_xyz_weights xyz;
	kg_xyz white;
} report;

static const double black[3] = {0, 0, 0};
static const double white_rgb[3] = {1, 1, 1};
static const double true_colour[3] = {0.1, 0.1, 0.1};
static const double est_colour[3] = {0.85, 0.33, 0.10};
static const double band_colour[3] = {0.99, 0.84, 0.74};
static const double no_data[3] = {0.55, 0.55, 0.55};
static const double light_grey[3] = {0.82, 0.82, 0.82};

static void report_free(report *r)
{
	free(r->m);
	free(r->confusion);
	free(r->background_by_class);
	free(r->cube);
	free(r->labels);
	for (int c = 0; r->class_names && c < r->nclasses; c++)
		free(r->class_names[c]);
	free(r->class_names);
	free(r->class_bits);
	free(r->class_first);
	free(r->table);
	free(r->regions);
	free(r->region_bits);
	for (int k = 0; k < r->nreg; k++)
		free(r->reg[k].votes);
	free(r->reg);
	free(r->estimate_material);
	demo_rerender_result_clear(&r->rr);
	kg_illuminant_free(&r->d65);
}

static kg_lab lab_d65(const report *r, const kg_spectrum *s)
{
	return kg_xyz_to_lab(kg_xyz_from_weights(&r->xyz, s), r->white);
}

static void srgb_d65(const report *r, const kg_spectrum *s, double rgb[3])
{
	kg_rgb c = kg_srgb_encode(kg_xyz_to_linear_srgb(kg_xyz_from_weights(&r->xyz, s), r->white));
	rgb[0] = fmin(fmax(c.r, 0), 1);
	rgb[1] = fmin(fmax(c.g, 0), 1);
	rgb[2] = fmin(fmax(c.b, 0), 1);
}

static void put_rgb8(unsigned char *px, const double rgb[3])
{
	for (int c = 0; c < 3; c++)
		px[c] = (unsigned char)lrint(fmin(fmax(rgb[c], 0.0), 1.0) * 255.0);
}

/* The materials a label names: "a" or "a|b|c" as a bit set of library indices, and the
 * first of them (-1 for none: unclassified, unknown, background). */
static int name_bits(const report *r, const char *name, int *first)
{
	int bits = 0;
	if (first)
		*first = -1;
	for (const char *p = name; *p;) {
		const char *bar = strchr(p, '|');
		size_t len = bar ? (size_t)(bar - p) : strlen(p);
		for (int j = 0; j < r->n && j < 30; j++)
			if (strlen(r->m[j].name) == len && !strncmp(p, r->m[j].name, len)) {
				bits |= 1 << j;
				if (first && *first < 0)
					*first = j;
			}
		if (!bar)
			break;
		p = bar + 1;
	}
	return bits;
}

static int popcount(int bits)
{
	int n = 0;
	for (; bits; bits &= bits - 1)
		n++;
	return n;
}

/* The whole cube in BIP, after checking it is the 61-band cube of the object. */
static int read_cube(demo_ctx *d, report *r)
{
	char *path = demo_path(d, "site/" DEMO_CAPTURE_OBJECT "/cube.hdr");
	kg_envi *e = NULL;
	int ret = kg_envi_open(path, &e, &d->err);
	if (!ret && (e->meta.bands != KG_NBANDS || e->meta.samples != r->width ||
	             e->meta.lines != r->height))
		ret = kg_fail(&d->err, KG_EINVAL, "%s: %d x %d x %d: expected %d x %d x %d", path,
		              e->meta.samples, e->meta.lines, e->meta.bands, r->width, r->height,
		              KG_NBANDS);
	if (!ret && !(r->cube = malloc(sizeof(float) * KG_NBANDS * r->width * r->height)))
		ret = kg_fail(&d->err, KG_ENOMEM, "%s: out of memory", path);
	if (!ret)
		ret = kg_envi_read(e, 0, 0, r->width, r->height, KG_LAYOUT_BIP, r->cube, &d->err);
	kg_envi_close(&e);
	free(path);
	return ret;
}

/* Labels per pixel and, for each class of the label map, the bit set of the materials
 * it holds (bit j: r->m[j]; none for unclassified, unknown and background): a compound
 * class "a|b" (materials the noise cannot split per pixel) holds each of its members,
 * and a pixel so labelled is right when its truth is one of them. */
static int read_labels(demo_ctx *d, report *r)
{
	char *path = demo_path(d, "site/" DEMO_CAPTURE_OBJECT "/labels.hdr");
	kg_envi *e = NULL;
	int ret = kg_envi_open(path, &e, &d->err);
	if (!ret && (e->meta.bands != 1 || e->meta.samples != r->width ||
	             e->meta.lines != r->height || e->meta.classes < 1 || !e->meta.class_names))
		ret = kg_fail(&d->err, KG_EINVAL,
		              "%s: expected a %d x %d ENVI classification file", path, r->width,
		              r->height);
	if (!ret) {
		r->nclasses = e->meta.classes;
		r->labels = malloc(sizeof(float) * r->width * r->height);
		r->class_names = calloc((size_t)r->nclasses, sizeof(char *));
		r->class_bits = calloc((size_t)r->nclasses, sizeof(int));
		r->class_first = calloc((size_t)r->nclasses, sizeof(int));
		r->background_by_class = calloc((size_t)r->nclasses + 1, sizeof(long));
		if (!r->labels || !r->class_names || !r->class_bits || !r->class_first ||
		    !r->background_by_class)
			ret = kg_fail(&d->err, KG_ENOMEM, "%s: out of memory", path);
	}
	for (int c = 0; !ret && c < r->nclasses; c++) {
		if (!(r->class_names[c] = strdup(e->meta.class_names[c])))
			ret = kg_fail(&d->err, KG_ENOMEM, "%s: out of memory", path);
		else
			r->class_bits[c] = name_bits(r, r->class_names[c], &r->class_first[c]);
	}
	if (!ret)
		ret = kg_envi_read(e, 0, 0, r->width, r->height, KG_LAYOUT_BIP, r->labels, &d->err);
	kg_envi_close(&e);
	free(path);
	return ret;
}

/* The label map's regions: the number of each pixel's region (labels_regions.hdr) and
 * the table of regions (labels_regions.csv): every region's decided label as a bit
 * set, and the regions of DEMO_REGION_MIN_PIXELS pixels or more in full. */
static int read_regions(demo_ctx *d, report *r)
{
	char *hdr = demo_path(d, "site/" DEMO_CAPTURE_OBJECT "/labels_regions.hdr");
	char *csv = demo_path(d, "site/" DEMO_CAPTURE_OBJECT "/labels_regions.csv");
	kg_envi *e = NULL;
	char *text = NULL;
	size_t len = 0;
	int ret = hdr && csv ? kg_envi_open(hdr, &e, &d->err)
	                     : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	if (!ret && (e->meta.bands != 1 || e->meta.samples != r->width ||
	             e->meta.lines != r->height))
		ret = kg_fail(&d->err, KG_EINVAL, "%s: expected one band of %d x %d", hdr, r->width,
		              r->height);
	if (!ret && !(r->regions = malloc(sizeof(float) * r->width * r->height)))
		ret = kg_fail(&d->err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = kg_envi_read(e, 0, 0, r->width, r->height, KG_LAYOUT_BIP, r->regions, &d->err);
	kg_envi_close(&e);
	if (!ret)
		ret = kg_read_file(csv, &text, &len, &d->err);
	/* two passes over the table: the largest region number, then the rows */
	for (int pass = 0; pass < 2 && !ret; pass++) {
		if (pass == 1) {
			r->region_bits = calloc((size_t)r->max_region + 1, sizeof(int));
			if (!r->region_bits) {
				ret = kg_fail(&d->err, KG_ENOMEM, "out of memory");
				break;
			}
		}
		char *line = strchr(text, '\n');
		while (!ret && line && *++line) {
			char *next = strchr(line, '\n');
			unsigned id;
			unsigned long long px;
			double posterior = NAN;
			char cls[KG_EST_CLASS_NAME_MAX], label[KG_EST_CLASS_NAME_MAX];
			if (sscanf(line, "%u,%llu,%255[^,],%255[^,],%lf", &id, &px, cls, label,
			           &posterior) < 4 || id > (1u << 26)) {
				ret = kg_fail(&d->err, KG_EINVAL, "%s: line '%.*s': expected region, "
				              "pixels, class, label, posterior, ...", csv,
				              (int)(next ? next - line : (long)strlen(line)), line);
				break;
			}
			if (pass == 0) {
				if (id > r->max_region)
					r->max_region = id;
			} else {
				r->region_bits[id] = name_bits(r, label, NULL);
				if (px >= DEMO_REGION_MIN_PIXELS) {
					region_eval *g = realloc(r->reg, sizeof(*g) * (size_t)(r->nreg + 1));
					if (!g) {
						ret = kg_fail(&d->err, KG_ENOMEM, "out of memory");
						break;
					}
					r->reg = g;
					g = &r->reg[r->nreg++];
					memset(g, 0, sizeof(*g));
					g->id = id;
					g->pixels = (long)px;
					snprintf(g->cls, sizeof(g->cls), "%s", cls);
					snprintf(g->label, sizeof(g->label), "%s", label);
					g->posterior = posterior;
					g->bits = r->region_bits[id];
					g->truth = -1;
					if (!(g->votes = calloc((size_t)r->n + 1, sizeof(long))))
						ret = kg_fail(&d->err, KG_ENOMEM, "out of memory");
				}
			}
			line = next;
		}
	}
	free(text);
	free(hdr);
	free(csv);
	return ret;
}

/* The regions of DEMO_REGION_MIN_PIXELS or more against the truth: mostly off the
 * object (the studio seen past it) or mostly beyond the searched angles, not judged;
 * else right when the label holds the majority material of its object pixels. */
static void judge_regions(demo_ctx *d, report *r)
{
	const kg_render_truth *t = d->truth;
	int *slot = calloc((size_t)r->max_region + 1, sizeof(int));
	if (!slot)
		return;
	for (int k = 0; k < r->nreg; k++)
		slot[r->reg[k].id] = k + 1;
	for (long i = 0; i < (long)r->width * r->height; i++) {
		float f = r->regions[i];
		if (!(f >= 1) || f > (float)r->max_region || !slot[(unsigned)f])
			continue;
		region_eval *g = &r->reg[slot[(unsigned)f] - 1];
		int c = t->label[i];
		g->votes[c]++;
		if (c) {
			g->object++;
			if (t->angle_deg[i] <= d->angles[1])
				g->searched++;
			else
				g->grazing++;
		}
	}
	for (int k = 0; k < r->nreg; k++) {
		region_eval *g = &r->reg[k];
		for (int c = 1; c <= r->n; c++)
			if (g->votes[c] && (g->truth < 0 || g->votes[c] > g->votes[g->truth + 1]))
				g->truth = c - 1;
		if (2 * g->object < g->pixels) {
			g->kind = REGION_BACKGROUND;
			r->nreg_background++;
		} else if (2 * g->searched < g->object) {
			g->kind = REGION_GRAZING;
			r->nreg_grazing++;
		} else {
			g->kind = REGION_JUDGED;
			g->right = g->truth >= 0 && (g->bits >> g->truth & 1);
			g->exact = g->right && g->bits == 1 << g->truth;
			r->nreg_judged++;
			r->nreg_right += g->right;
			r->nreg_exact += g->exact;
		}
	}
	free(slot);
}

/* Each region's material for the re-render, from the labels of its material's judged
 * pixels (demo_private.h: the material identifies the region in the demo's scene). */
static void choose_estimates(demo_ctx *d, report *r, const long *class_votes,
                             const long *resolved, const long *unresolved)
{
	for (int j = 0; j < r->n; j++) {
		material_eval *m = &r->m[j];
		const long *v = class_votes + (size_t)j * r->nclasses;
		m->est_class = -1;
		for (int c = 0; c < r->nclasses; c++)
			if (r->class_bits[c] && r->class_first[c] >= 0 && v[c] &&
			    (m->est_class < 0 || v[c] > v[m->est_class]))
				m->est_class = c;
		if (m->est_class < 0) {
			m->est_material = j;
			m->est_how = "no pixel with a material label: its true material kept";
			continue;
		}
		m->est_votes = v[m->est_class];
		int bits = r->class_bits[m->est_class];
		m->est_material = r->class_first[m->est_class];
		if (popcount(bits) == 1) {
			m->est_how = "its majority label";
			continue;
		}
		/* a compound: the member the label map's regions resolved most of these pixels
		 * into, if they resolved more than they left compound; else the first member */
		const long *res = resolved + (size_t)j * r->n;
		int best = -1;
		for (int k = 0; k < r->n; k++)
			if ((bits >> k & 1) && res[k] && (best < 0 || res[k] > res[best]))
				best = k;
		if (best >= 0 && res[best] > unresolved[j]) {
			m->est_material = best;
			m->est_how = "the member its regions resolved";
		} else {
			m->est_how = "the compound's first member (its regions did not resolve it)";
		}
	}
	for (int k = 0; k < d->nregions; k++)
		r->estimate_material[k] = r->m[d->region_material[k]].est_material;
}

/* Compare every object pixel with its truth. */
static int evaluate(demo_ctx *d, report *r)
{
	const kg_render_truth *t = d->truth;
	r->width = t->width;
	r->height = t->height;
	r->n = t->nclasses - 1; /* class 0 is the background */
	r->m = calloc((size_t)r->n, sizeof(*r->m));
	r->confusion = calloc((size_t)r->n * (r->n + 1), sizeof(long));
	r->estimate_material = calloc((size_t)d->nregions, sizeof(int));
	if (!r->m || !r->confusion || !r->estimate_material)
		return kg_fail(&d->err, KG_ENOMEM, "out of memory");
	int ret = kg_illuminant_by_name("D65", &r->d65, &d->err);
	if (!ret)
		ret = demo_truth_table(d, &r->table);
	if (ret)
		return ret;
	kg_xyz_weights_reflectance(r->d65, &r->xyz);
	r->white = kg_illuminant_white(r->d65);
	for (int j = 0; j < r->n; j++) {
		r->m[j].name = t->class_names[j + 1];
		r->m[j].region = -1;
	}
	for (int k = d->nregions - 1; k >= 0; k--)
		r->m[d->region_material[k]].region = k;

	ret = read_cube(d, r);
	if (!ret)
		ret = read_labels(d, r);
	if (!ret)
		ret = read_regions(d, r);
	if (ret)
		return ret;
	long *class_votes = calloc((size_t)r->n * r->nclasses, sizeof(long));
	long *resolved = calloc((size_t)r->n * r->n, sizeof(long));
	long *unresolved = calloc((size_t)r->n, sizeof(long));
	if (!class_votes || !resolved || !unresolved)
		ret = kg_fail(&d->err, KG_ENOMEM, "out of memory");
	const int nang = (int)(90 * DEMO_TRUTH_ANGLE_SCALE) + 1;
	for (long i = 0; !ret && i < (long)r->width * r->height; i++) {
		int ti = t->label[i] - 1;
		int c = (int)r->labels[i];
		c = c >= 0 && c < r->nclasses ? c : -1;
		if (ti < 0) {
			r->background++;
			r->background_by_class[c >= 0 ? c : r->nclasses]++;
			continue;
		}
		material_eval *m = &r->m[ti];
		/* A pixel at a region's border is mixed with its neighbour by the demosaicing
		 * (bilinear: its 3 x 3 neighbourhood), and by the render's pixel, which its
		 * samples may share between two surfaces: no single material is its truth.
		 * Counted apart, not judged. */
		int x = (int)(i % r->width), y = (int)(i / r->width), mixed = 0;
		for (int dy = -1; dy <= 1 && !mixed; dy++)
			for (int dx = -1; dx <= 1 && !mixed; dx++) {
				int xx = x + dx, yy = y + dy;
				mixed = xx < 0 || yy < 0 || xx >= r->width || yy >= r->height ||
				        t->label[(long)yy * r->width + xx] != t->label[i];
			}
		if (mixed) {
			m->mixed++;
			r->mixed++;
			continue;
		}
		int bits = c >= 0 ? r->class_bits[c] : 0, ok = bits >> ti & 1;
		/* Beyond the searched angles (the rim's grazing pixels): counted apart. */
		if (!(t->angle_deg[i] <= d->angles[1])) {
			m->grazing++;
			m->grazing_correct += ok;
			r->grazing++;
			r->grazing_correct += ok;
			continue;
		}
		int p = ok ? ti : c >= 0 && r->class_first[c] >= 0 ? r->class_first[c] : r->n;
		m->pixels++;
		r->pixels++;
		r->confusion[(long)ti * (r->n + 1) + p]++;
		if (ok) {
			m->correct++;
			r->correct++;
		}
		if (p == r->n)
			r->unclassified++;
		if (c >= 0) {
			class_votes[(size_t)ti * r->nclasses + c]++;
			float f = r->regions[i];
			int rb = f >= 1 && f <= (float)r->max_region ? r->region_bits[(unsigned)f] : 0;
			if (popcount(bits) > 1) {
				if (popcount(rb) == 1 && (rb & bits))
					for (int k = 0; k < r->n; k++)
						resolved[(size_t)ti * r->n + k] += rb >> k & 1;
				else
					unresolved[ti]++;
			}
		}
		kg_spectrum est;
		for (int b = 0; b < KG_NBANDS; b++)
			est.v[b] = r->cube[i * KG_NBANDS + b];
		if (!kg_spectrum_isfinite(&est)) {
			m->flagged++;
			continue;
		}
		long a = lrint(t->angle_deg[i] * DEMO_TRUTH_ANGLE_SCALE);
		const float *tr = r->table + ((size_t)ti * nang + (size_t)a) * KG_NBANDS;
		kg_spectrum truth;
		for (int b = 0; b < KG_NBANDS; b++) {
			truth.v[b] = tr[b];
			m->tsum[b] += tr[b];
			m->sum[b] += est.v[b];
			m->sumsq[b] += est.v[b] * est.v[b];
		}
		m->angle_sum += t->angle_deg[i];
		m->rmse_sum += kg_spectrum_rmse(&est, &truth);
		/* The estimate carries the light the pixel receives (the studio's level in its
		 * mirror direction, the lobes): scaled onto the truth by least squares, what
		 * is left is its shape and colour. */
		double et = 0, ee = 0;
		for (int b = 0; b < KG_NBANDS; b++) {
			et += est.v[b] * truth.v[b];
			ee += est.v[b] * est.v[b];
		}
		double k = ee > 0 ? et / ee : 1.0;
		kg_spectrum scaled;
		for (int b = 0; b < KG_NBANDS; b++)
			scaled.v[b] = k * est.v[b];
		m->scale_sum += k;
		m->srmse_sum += kg_spectrum_rmse(&scaled, &truth);
		m->de00_sum += kg_ciede2000(lab_d65(r, &scaled), lab_d65(r, &truth));
	}
	for (int j = 0; !ret && j < r->n; j++) {
		material_eval *m = &r->m[j];
		double n = (double)(m->pixels - m->flagged);
		for (int b = 0; b < KG_NBANDS; b++) {
			m->truth.v[b] = n > 0 ? m->tsum[b] / n : NAN;
			m->mean.v[b] = n > 0 ? m->sum[b] / n : NAN;
			double var = n > 1 ? (m->sumsq[b] - n * m->mean.v[b] * m->mean.v[b]) / (n - 1) : 0;
			m->sd.v[b] = sqrt(fmax(var, 0));
		}
		m->rmse = n > 0 ? m->rmse_sum / n : NAN;
		m->de00 = n > 0 ? m->de00_sum / n : NAN;
		m->scale = n > 0 ? m->scale_sum / n : NAN;
		m->srmse = n > 0 ? m->srmse_sum / n : NAN;
		m->angle = n > 0 ? m->angle_sum / n : NAN;
	}
	if (!ret) {
		judge_regions(d, r);
		choose_estimates(d, r, class_votes, resolved, unresolved);
	}
	free(class_votes);
	free(resolved);
	free(unresolved);
	return ret;
}

static double map_x(const kg_axes *ax, double v)
{
	return ax->x + (v - ax->xmin) / (ax->xmax - ax->xmin) * ax->w;
}

static double map_y(const kg_axes *ax, double v)
{
	v = fmin(fmax(v, ax->ymin), ax->ymax);
	return ax->y + ax->h - (v - ax->ymin) / (ax->ymax - ax->ymin) * ax->h;
}

/* The paper's Figs. 11-12: one panel per material of the object, true solid (the
 * reflectance at each judged pixel's own angle, averaged), mean estimate dashed in a
 * band of +-1 sd over the material's pixels. */
static int plot_spectra(demo_ctx *d, const report *r)
{
	const int cols = 5, cell_w = 310, cell_h = 300, left = 80, top = 140;
	int shown[64], nshown = 0;
	for (int j = 0; j < r->n && nshown < 64; j++)
		if (r->m[j].pixels > r->m[j].flagged)
			shown[nshown++] = j;
	int rows = nshown ? (nshown + cols - 1) / cols : 1;
	kg_plot *p = NULL;
	char *path = demo_path(d, "spectra_by_material.png");
	int ret = kg_plot_new(left + cols * cell_w, top + rows * cell_h, &p, &d->err);
	if (ret) {
		free(path);
		return ret;
	}
	double wl[KG_NBANDS];
	for (int b = 0; b < KG_NBANDS; b++)
		wl[b] = kg_band_nm(b);
	kg_plot_text(p, (left + cols * cell_w) / 2.0, 32, 18, KG_ALIGN_CENTER, NULL,
	             "Estimated against true reflectance per material (cf. the paper's Figs. 11-12)");
	kg_plot_text(p, (left + cols * cell_w) / 2.0, 56, 13, KG_ALIGN_CENTER, NULL,
	             "the tsuba photographed by the site camera under CIE %s, PCA K = %d, s = B M M2 "
	             "rho; over each material's judged pixels (%g-%g deg); true: its reflectance at "
	             "each pixel's angle, averaged; swatches: true | estimated under D65",
	             DEMO_SITE_ILLUMINANT, d->cam->K, d->angles[0], d->angles[1]);
	kg_plot_text(p, (left + cols * cell_w) / 2.0, 76, 13, KG_ALIGN_CENTER, NULL,
	             "the estimate carries the light each pixel receives; under each panel: RMSE, "
	             "then x the mean least-squares scale onto the truth, the RMSE and dE00 (D65) "
	             "after it, and the share labelled right");
	double lx = (left + cols * cell_w) / 2.0 - 300;
	kg_plot_legend(p, lx, 104, true_colour, 0, "true");
	kg_plot_legend(p, lx + 150, 104, est_colour, 1, "estimated, mean");
	kg_plot_fill_rect(p, lx + 360, 98, 30, 12, band_colour);
	kg_plot_text(p, lx + 398, 109, 12, KG_ALIGN_LEFT, NULL, "estimated, +-1 sd");
	for (int k = 0; k < nshown; k++) {
		int j = shown[k];
		const material_eval *m = &r->m[j];
		double x = left + (k % cols) * cell_w, y = top + (k / cols) * cell_h + 20;
		/* Each panel's own scale, so dark materials (lacquer) show their shape too. */
		double top_value = 0;
		for (int b = 0; b < KG_NBANDS; b++)
			top_value = fmax(top_value, fmax(m->truth.v[b], m->mean.v[b] + m->sd.v[b]));
		double ymax = fmax(0.1, ceil(top_value * 1.05 * 10) / 10);
		kg_axes ax = kg_plot_axes(p, x, y, 240, 200, 400, 700, 0, ymax,
		                          k / cols == rows - 1 ? "wavelength (nm)" : NULL,
		                          k % cols == 0 ? "reflectance" : NULL, NULL);
		kg_plot_text(p, x, y - 10, 14, KG_ALIGN_LEFT, NULL, "%s", m->name);
		double sw[3];
		srgb_d65(r, &m->truth, sw);
		kg_plot_fill_rect(p, x + 196, y - 24, 22, 18, sw);
		srgb_d65(r, &m->mean, sw);
		kg_plot_fill_rect(p, x + 218, y - 24, 22, 18, sw);
		kg_plot_stroke_rect(p, x + 196, y - 24, 44, 18, black, 1);
		for (int b = 0; b < KG_NBANDS; b++) {
			double x0 = map_x(&ax, fmax(wl[b] - 2.5, 400)), x1 = map_x(&ax, fmin(wl[b] + 2.5, 700));
			double y0 = map_y(&ax, m->mean.v[b] + m->sd.v[b]);
			double y1 = map_y(&ax, m->mean.v[b] - m->sd.v[b]);
			if (isfinite(y0) && isfinite(y1))
				kg_plot_fill_rect(p, x0, y0, x1 - x0, y1 - y0, band_colour);
		}
		kg_plot_stroke_rect(p, ax.x, ax.y, ax.w, ax.h, black, 1);
		kg_plot_line(p, &ax, wl, m->truth.v, KG_NBANDS, true_colour, 2, 0);
		kg_plot_line(p, &ax, wl, m->mean.v, KG_NBANDS, est_colour, 2, 1);
		kg_plot_text(p, x + 8, y + 216 + (k / cols == rows - 1 ? 40 : 18), 12,
		             KG_ALIGN_LEFT, NULL, "RMSE %.3f | x%.2f: %.3f, dE00 %.1f | %.0f %%",
		             m->rmse, m->scale, m->srmse, m->de00,
		             m->pixels ? 100.0 * m->correct / m->pixels : 0.0);
	}
	ret = kg_plot_save_png(p, path, &d->err);
	if (!ret)
		demo_wrote(d, path, "estimated against true spectra, one panel per material");
	kg_plot_free(&p);
	free(path);
	return ret;
}

/* Rows: the object's materials; columns: predicted, every material of the library
 * numbered in library order (the rows carry their numbers). */
static int plot_confusion(demo_ctx *d, const report *r)
{
	int ncol = r->n + (r->unclassified > 0);
	int rowm[64], nrows = 0;
	for (int j = 0; j < r->n && nrows < 64; j++)
		if (r->m[j].pixels)
			rowm[nrows++] = j;
	const int cell = 62, left = 250, top = 110;
	kg_plot *p = NULL;
	char *path = demo_path(d, "confusion.png");
	int ret = kg_plot_new(left + ncol * cell + 110, top + nrows * cell + 70, &p, &d->err);
	if (ret) {
		free(path);
		return ret;
	}
	kg_plot_text(p, (left + ncol * cell + 110) / 2.0, 30, 17, KG_ALIGN_CENTER, NULL,
	             "Labels of the object's pixels against the truth (camera-space matching)");
	kg_plot_text(p, left + ncol * cell / 2.0, top - 40, 13, KG_ALIGN_CENTER, NULL,
	             "predicted material (library order; a compound label counts on the diagonal "
	             "when it holds the truth, else as its first member)%s",
	             r->unclassified ? "; u = unclassified, unknown, background" : "");
	kg_plot_text(p, left - 10, top - 12, 13, KG_ALIGN_RIGHT, NULL, "true material");
	kg_plot_text(p, left + ncol * cell + 55, top - 12, 13, KG_ALIGN_CENTER, NULL, "recall");
	for (int c = 0; c < ncol; c++) {
		if (c < r->n)
			kg_plot_text(p, left + c * cell + cell / 2.0, top - 12, 13, KG_ALIGN_CENTER,
			             NULL, "%d", c + 1);
		else
			kg_plot_text(p, left + c * cell + cell / 2.0, top - 12, 13, KG_ALIGN_CENTER,
			             NULL, "u");
	}
	for (int row = 0; row < nrows; row++) {
		int t = rowm[row];
		const material_eval *m = &r->m[t];
		double y = top + row * cell;
		kg_plot_text(p, left - 10, y + cell / 2.0 + 5, 13, KG_ALIGN_RIGHT, NULL, "%d  %s",
		             t + 1, m->name);
		for (int c = 0; c < ncol; c++) {
			int col = c < r->n ? c : r->n;
			long count = r->confusion[(long)t * (r->n + 1) + col];
			double f = m->pixels ? (double)count / m->pixels : 0;
			double rgb[3] = {1 - 0.85 * f, 1 - 0.65 * f, 1 - 0.3 * f};
			double x = left + c * cell;
			kg_plot_fill_rect(p, x, y, cell, cell, rgb);
			kg_plot_stroke_rect(p, x, y, cell, cell, no_data, 0.5);
			if (count) {
				const double *ink = f > 0.5 ? white_rgb : black;
				kg_plot_text(p, x + cell / 2.0, y + cell / 2.0, 13, KG_ALIGN_CENTER, ink,
				             "%ld", count);
				kg_plot_text(p, x + cell / 2.0, y + cell / 2.0 + 16, 10, KG_ALIGN_CENTER,
				             ink, "%.0f %%", 100 * f);
			}
		}
		kg_plot_stroke_rect(p, left + t * cell, y, cell, cell, black, 2);
		kg_plot_text(p, left + ncol * cell + 55, y + cell / 2.0 + 5, 13, KG_ALIGN_CENTER,
		             NULL, "%.1f %%", m->pixels ? 100.0 * m->correct / m->pixels : 0.0);
	}
	kg_plot_text(p, left, top + nrows * cell + 35, 14, KG_ALIGN_LEFT, NULL,
	             "accuracy %.1f %% of %ld object pixels at %g-%g deg, not at a border; the "
	             "diagonal is outlined",
	             r->pixels ? 100.0 * r->correct / r->pixels : 0.0, r->pixels, d->angles[0],
	             d->angles[1]);
	ret = kg_plot_save_png(p, path, &d->err);
	if (!ret)
		demo_wrote(d, path, "confusion matrix (pixel counts, row fractions)");
	kg_plot_free(&p);
	free(path);
	return ret;
}

/* The object three ways: as the site camera recorded it, and the true (each pixel's
 * material at its angle) and the estimated reflectance rendered under D65. */
static int plot_object(demo_ctx *d, const report *r)
{
	const kg_render_truth *t = d->truth;
	const kg_image *photo = d->photos.object;
	const int gap = 30, top = 70, W = r->width, H = r->height;
	const int nang = (int)(90 * DEMO_TRUTH_ANGLE_SCALE) + 1;
	kg_plot *p = NULL;
	char *path = demo_path(d, "object_d65.png");
	unsigned char *buf = malloc(3 * (size_t)W * (size_t)H * 3);
	int ret = buf ? kg_plot_new(3 * W + 4 * gap, H + top + 20, &p, &d->err)
	              : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	if (ret) {
		free(buf);
		free(path);
		return ret;
	}
	static const char *titles[3] = {
		"site camera image (camera RGB, as recorded)",
		"true reflectance at each pixel's angle, rendered under D65",
		"estimated reflectance, rendered under D65",
	};
	size_t plane = 3 * (size_t)W * (size_t)H;
	for (long i = 0; i < (long)W * H; i++) {
		double rgb[3];
		kg_rgb cam = kg_srgb_encode((kg_rgb){photo->data[3 * i] / DEMO_WHITE_LEVEL,
		                                     photo->data[3 * i + 1] / DEMO_WHITE_LEVEL,
		                                     photo->data[3 * i + 2] / DEMO_WHITE_LEVEL});
		rgb[0] = cam.r, rgb[1] = cam.g, rgb[2] = cam.b;
		put_rgb8(buf + 3 * i, rgb);
		kg_spectrum s;
		if (t->label[i]) {
			long a = lrint(t->angle_deg[i] * DEMO_TRUTH_ANGLE_SCALE);
			const float *tr =
				r->table + ((size_t)(t->label[i] - 1) * nang + (size_t)a) * KG_NBANDS;
			for (int b = 0; b < KG_NBANDS; b++)
				s.v[b] = tr[b];
			srgb_d65(r, &s, rgb);
			put_rgb8(buf + plane + 3 * i, rgb);
		} else {
			put_rgb8(buf + plane + 3 * i, no_data);
		}
		for (int b = 0; b < KG_NBANDS; b++)
			s.v[b] = r->cube[i * KG_NBANDS + b];
		if (kg_spectrum_isfinite(&s))
			srgb_d65(r, &s, rgb);
		else
			memcpy(rgb, no_data, sizeof(rgb));
		put_rgb8(buf + 2 * plane + 3 * i, rgb);
	}
	for (int k = 0; k < 3; k++) {
		kg_plot_text(p, gap + k * (W + gap) + W / 2.0, top - 16, 14, KG_ALIGN_CENTER, NULL,
		             "%s", titles[k]);
		kg_plot_image(p, gap + k * (W + gap), top, buf + k * plane, W, H);
	}
	ret = kg_plot_save_png(p, path, &d->err);
	if (!ret)
		demo_wrote(d, path, "the object: camera image, true and estimated colour");
	kg_plot_free(&p);
	free(buf);
	free(path);
	return ret;
}

/* A label map's colour at display pixel (x, y): a material in its series colour, a
 * compound class in diagonal stripes of its members' colours, unknown white,
 * background (or the truth's "not the object") black, unclassified light grey. */
static void class_colour(const report *r, int c, int x, int y, double rgb[3])
{
	if (c < 0 || c >= r->nclasses) {
		memcpy(rgb, light_grey, sizeof(light_grey));
		return;
	}
	int bits = r->class_bits[c], n = popcount(bits);
	if (n == 0) {
		const char *name = r->class_names[c];
		const double *v = !strcmp(name, "unknown") ? white_rgb
		                  : !strcmp(name, "background") ? black : light_grey;
		memcpy(rgb, v, sizeof(double) * 3);
		return;
	}
	int pick = n > 1 ? ((x + y) / 5) % n : 0;
	for (int j = 0; j < r->n; j++)
		if ((bits >> j & 1) && pick-- == 0) {
			kg_series_colour(j, rgb);
			return;
		}
}

static void xyz_to_rgb8(const float *xyz, kg_xyz white, unsigned char *px)
{
	kg_xyz w100 = {100.0 * white.X, 100.0 * white.Y, 100.0 * white.Z};
	kg_rgb lin = kg_xyz_to_linear_srgb((kg_xyz){100.0 * xyz[0], 100.0 * xyz[1],
	                                            100.0 * xyz[2]}, w100);
	lin.r = fmax(lin.r, 0.0);
	lin.g = fmax(lin.g, 0.0);
	lin.b = fmax(lin.b, 0.0);
	kg_rgb_to_u8(kg_srgb_encode(lin), px);
}

#define DE00_SCALE 5.0 /* the colour map's top, dE00 */

/* What a person looks at: the truth's label map beside the estimated one, and the
 * object rendered under D65 from the truth beside its re-render from the estimated
 * labels, with the CIEDE2000 between them per pixel. */
static int plot_truth_vs_estimate(demo_ctx *d, const report *r)
{
	const kg_render_truth *t = d->truth;
	const int gap = 30, LW = 560, LH = LW * r->height / r->width, legend_w = 250;
	const int top1 = 110, top2 = top1 + LH + 80;
	const demo_rerender_result *rr = &r->rr;
	int RW = rr->available ? rr->width : 0, RH = rr->available ? rr->height : 0;
	int width = 2 * LW + 3 * gap + legend_w;
	if (rr->available && 3 * RW + 4 * gap + 80 > width)
		width = 3 * RW + 4 * gap + 80;
	int height = rr->available ? top2 + RH + 70 + 17 * d->nregions : top2 + 40;
	kg_plot *p = NULL;
	char *path = demo_path(d, "truth_vs_estimate.png");
	size_t lsize = 3 * (size_t)LW * (size_t)LH, rsize = 3 * (size_t)RW * (size_t)RH;
	unsigned char *buf = malloc(2 * lsize + 3 * rsize + 1);
	int ret = buf ? kg_plot_new(width, height, &p, &d->err)
	              : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	if (ret) {
		free(buf);
		free(path);
		return ret;
	}
	kg_plot_text(p, width / 2.0, 32, 18, KG_ALIGN_CENTER, NULL,
	             "The object (fixtures/%s): truth against estimate", DEMO_OBJECT_SCENE);
	kg_plot_text(p, width / 2.0, 56, 12, KG_ALIGN_CENTER, NULL,
	             "accuracy %.1f %% of the %ld object pixels at %g-%g deg not at a border; "
	             "regions of %d pixels or more on the object: %d of %d with their true label",
	             r->pixels ? 100.0 * r->correct / r->pixels : 0.0, r->pixels, d->angles[0],
	             d->angles[1], DEMO_REGION_MIN_PIXELS, r->nreg_right, r->nreg_judged);
	/* the two label maps, sampled to LW x LH */
	for (int y = 0; y < LH; y++)
		for (int x = 0; x < LW; x++) {
			long sx = (long)((x + 0.5) * r->width / LW), sy = (long)((y + 0.5) * r->height / LH);
			long i = sy * r->width + sx;
			double rgb[3];
			if (t->label[i])
				kg_series_colour(t->label[i] - 1, rgb);
			else
				memcpy(rgb, black, sizeof(rgb));
			put_rgb8(buf + 3 * ((size_t)y * LW + x), rgb);
			class_colour(r, (int)r->labels[i], x, y, rgb);
			if (!t->label[i]) /* off the object: dimmed */
				for (int c = 0; c < 3; c++)
					rgb[c] = 0.35 * rgb[c] + 0.65 * light_grey[c];
			put_rgb8(buf + lsize + 3 * ((size_t)y * LW + x), rgb);
		}
	kg_plot_text(p, gap + LW / 2.0, top1 - 12, 14, KG_ALIGN_CENTER, NULL,
	             "truth: the material each pixel shows (the render's)");
	kg_plot_text(p, 2 * gap + LW * 1.5, top1 - 12, 14, KG_ALIGN_CENTER, NULL,
	             "estimated: kogei process's labels (off the object dimmed)");
	kg_plot_image(p, gap, top1, buf, LW, LH);
	kg_plot_image(p, 2 * gap + LW, top1, buf + lsize, LW, LH);
	/* the legend */
	double lx = 3 * gap + 2 * LW, ly = top1 + 4;
	for (int j = 0; j < r->n; j++, ly += 22) {
		double rgb[3];
		kg_series_colour(j, rgb);
		kg_plot_fill_rect(p, lx, ly, 26, 16, rgb);
		kg_plot_text(p, lx + 34, ly + 13, 12, KG_ALIGN_LEFT, NULL, "%d %s", j + 1,
		             r->m[j].name);
	}
	static const struct {
		const char *text;
		const double *rgb;
	} extra[] = {{"not the object / background", black}, {"unknown", white_rgb},
	             {"unclassified", light_grey}};
	for (size_t k = 0; k < sizeof(extra) / sizeof(extra[0]); k++, ly += 22) {
		kg_plot_fill_rect(p, lx, ly, 26, 16, extra[k].rgb);
		kg_plot_stroke_rect(p, lx, ly, 26, 16, no_data, 0.5);
		kg_plot_text(p, lx + 34, ly + 13, 12, KG_ALIGN_LEFT, NULL, "%s", extra[k].text);
	}
	kg_plot_text(p, lx, ly + 13, 12, KG_ALIGN_LEFT, NULL, "compound class 'a|b':");
	kg_plot_text(p, lx, ly + 31, 12, KG_ALIGN_LEFT, NULL, "stripes of its members");
	if (!rr->available) {
		kg_plot_text(p, width / 2.0, top2, 14, KG_ALIGN_CENTER, NULL,
		             "re-render skipped: kogei was built without Embree 3 (libembree-dev)");
	} else {
		unsigned char *rb = buf + 2 * lsize;
		/* the renders' scale: Y = 1 for the white */
		kg_xyz wd65 = {r->white.X / r->white.Y, 1.0, r->white.Z / r->white.Y};
		for (long i = 0; i < (long)RW * RH; i++) {
			xyz_to_rgb8(rr->truth->data + 3 * i, wd65, rb + 3 * i);
			xyz_to_rgb8(rr->estimate->data + 3 * i, wd65, rb + rsize + 3 * i);
			double rgb[3];
			if (isfinite(rr->de00[i]))
				kg_colormap(rr->de00[i] / DE00_SCALE, rgb);
			else
				memcpy(rgb, light_grey, sizeof(rgb));
			put_rgb8(rb + 2 * rsize + 3 * i, rgb);
		}
		static const char *titles[3] = {
			"rendered from the truth (D65)",
			"re-rendered from the estimated labels (D65)",
			"CIEDE2000 between them",
		};
		for (int k = 0; k < 3; k++) {
			kg_plot_text(p, gap + k * (RW + gap) + RW / 2.0, top2 - 12, 14, KG_ALIGN_CENTER,
			             NULL, "%s", titles[k]);
			kg_plot_image(p, gap + k * (RW + gap), top2, rb + k * rsize, RW, RH);
		}
		kg_plot_colorbar(p, 4 * gap + 3 * RW - 10, top2 + 20, 18, RH - 20, 0, DE00_SCALE,
		                 "dE00");
		kg_plot_text(p, gap, top2 + RH + 26, 13, KG_ALIGN_LEFT, NULL,
		             "CIEDE2000 over the %ld object pixels: mean %.2f, 90th percentile %.2f, "
		             "largest %.1f (the colour map stops at %g). Each region in the material "
		             "its pixels' labels give:",
		             rr->pixels, rr->de00_mean, rr->de00_p90, rr->de00_max, DE00_SCALE);
		for (int k = 0; k < d->nregions; k++) {
			char name[32];
			demo_region_name(d->region_id[k], name, sizeof(name));
			const material_eval *m = &r->m[d->region_material[k]];
			kg_plot_text(p, gap, top2 + RH + 50 + k * 17, 12, KG_ALIGN_LEFT, NULL,
			             "%s (%s): %s, from the label %s, %s", name, m->name,
			             kg_material_library_get(d->lib, r->estimate_material[k])->name,
			             m->est_class >= 0 ? r->class_names[m->est_class] : "-", m->est_how);
		}
	}
	ret = kg_plot_save_png(p, path, &d->err);
	if (!ret)
		demo_wrote(d, path, "truth against estimate: label maps, renders, dE00 map");
	kg_plot_free(&p);
	free(buf);
	free(path);
	return ret;
}

static void write_summary(demo_ctx *d, const report *r, FILE *fp)
{
	const kg_reference *ref = d->ref;
	const kg_camera_calib *cam = d->cam;
	const kg_spectral_map *map = &ref->maps[cam->method];
	fprintf(fp, "# kogei demo: a simulated session\n\n");
	fprintf(fp, "Written by `kogei demo` (kogei %s). Everything below was simulated with "
	            "fixed seeds, so every run gives the same numbers.\n\n", KG_VERSION);
	fprintf(fp, "## What was run\n\n");
	const demo_chart_shot *rs = &d->shots[0], *ss = &d->shots[1];
	const demo_spectro_run *sr = &d->spectro;
	fprintf(fp, "1. **Chart spectra** (measure -> `%s`): the %d patches of the chart measured "
	            "one by one with the simulated spectrophotometer `%s` (%s, serial %s): dark "
	            "reference, white reference (flat 0.99 standard), then each patch; %.0f ms "
	            "integration, %d scans averaged, electrical dark subtracted, reflectance "
	            "(S - D) / (W - D) x 0.99 resampled to 400-700 nm every 5 nm.\n",
	        DEMO_CHART_SPECTRA, sr->npatches, DEMO_SPECTRO, sr->model, sr->serial,
	        sr->integration_us / 1e3, sr->scans);
	fprintf(fp, "0. **The sessions** (`lab-session/`, `site-session/`): the bundled "
	            "recording `fixtures/%s` (raw frames from the simulated sensor, recorded by "
	            "`fixtures/demo/make_session.sh` with `kogei acquire`) replayed through the "
	            "`replay:` camera and averaged again by acquire/; each capture's mean is "
	            "checked against the sha256 the recording's manifest holds. Both are then "
	            "processed as `kogei process` processes a session.\n",
	        DEMO_SESSION);
	fprintf(fp, "2. **Reference calibration** (`kogei process lab-session --spectra` -> "
	            "`lab/reference.json`): the %d "
	            "CIE 13.3 test colour samples of `%s` (colord-data), mounted in the AprilTag "
	            "frame `%s` (`fixtures/%s`), photographed by the model camera `%s` under %s "
	            "(the session's capture `%s`: tilt %g deg, blur %g px, vignetting %g, noise "
	            "%s (full well:read noise:bits), seed %llu); the chart found by its tags and "
	            "sampled (`lab/chart_overlay.png`); S: the "
	            "measured spectra of `%s`.\n",
	        d->npatches, DEMO_CHART, d->layout_name, DEMO_CHART_LAYOUT,
	        DEMO_REFERENCE_CAMERA, DEMO_REFERENCE_ILLUMINANT, DEMO_CAPTURE_REFERENCE,
	        rs->tilt_deg, rs->blur_px, rs->vignetting, rs->noise,
	        (unsigned long long)rs->seed, DEMO_CHART_SPECTRA);
	fprintf(fp, "3. **Site calibration** (`kogei process site-session --reference "
	            "lab/reference.json` -> `site/camera.json`): the same chart "
	            "photographed by another model camera, `%s`, under CIE %s "
	            "(the session's capture `" DEMO_CAPTURE_SITE "`: tilt %g deg, rotated %g deg, blur %g px, vignetting %g, "
	            "noise %s, seed %llu), found and sampled the same way "
	            "(`site/chart_overlay.png`).\n",
	        DEMO_SITE_CAMERA, DEMO_SITE_ILLUMINANT, ss->tilt_deg, ss->rotate_deg, ss->blur_px,
	        ss->vignetting, ss->noise, (unsigned long long)ss->seed);
	fprintf(fp, "4. **Object** (the session's capture `" DEMO_CAPTURE_OBJECT "`, as "
	            "`object.tif`): a tsuba with inlays, `fixtures/" DEMO_OBJECT_SCENE "`, its "
	            "%d regions each in one material of the default library, in a grey studio "
	            "under CIE %s (so every metal has light in its mirror direction), seen "
	            "obliquely; rendered noise-free through the site camera's sensitivities at "
	            "the charts' white level (`kogei render --camera`) and photographed raw by "
	            "the same sim: camera as the site chart (noise %s, seed %d). Its truth, "
	            "recorded from the same render (`fixtures/" DEMO_TRUTH_LABELS "`, "
	            "`fixtures/" DEMO_TRUTH_ANGLE "`): the material and the incidence angle of "
	            "each pixel, written out as `object_truth_labels.hdr`, "
	            "`object_truth_angle.hdr` and `object_truth.hdr` (each pixel's material at "
	            "its angle).\n",
	        d->nregions, DEMO_SITE_ILLUMINANT, DEMO_SITE_NOISE, DEMO_SEED_OBJECT);
	fprintf(fp, "5. **Estimate** (`site/object/cube.hdr`, ENVI float32 BSQ, 61 bands "
	            "400-700 nm) and **classify** (`site/object/labels.hdr`, `.json`, `.png`), "
	            "the scene and the operator's report `site/report.html`, by kogei process.\n\n");

	fprintf(fp, "## Chart spectra (spectrophotometer)\n\n");
	fprintf(fp, "The spectra the calibration uses, as measured, against the tabulated "
	            "spectra of `%s` that the simulated instrument measured (its lamp, detector, "
	            "dark current and noise in between), on the 61-band grid.\n\n",
	        DEMO_CHART);
	fprintf(fp, "Measured vs file: RMSE **%.4f** mean over the %d patches, worst %.4f (%s); "
	            "largest |difference| %.4f (%s at %.0f nm); %d warning(s); %.0f ms for dark, "
	            "white and the patches.\n\n",
	        sr->rmse_mean, sr->npatches, sr->rmse_max, d->patch_ids[sr->rmse_max_at],
	        sr->diff_max, d->patch_ids[sr->diff_max_at], sr->diff_max_nm, sr->nwarnings,
	        sr->ms);
	fprintf(fp, "| patch | RMSE | max abs diff |\n|---|---:|---:|\n");
	for (int i = 0; i < sr->npatches && i < DEMO_MAX_PATCHES; i++)
		fprintf(fp, "| %s %s | %.4f | %.4f |\n", d->patch_ids[i], d->patch_names[i],
		        sr->rmse[i], sr->max_diff[i]);
	fprintf(fp, "\n");

	fprintf(fp, "## Chart detection\n\n");
	fprintf(fp, "`kg_chart_detect` with its defaults on each photograph as written: AprilTag "
	            "%s frame, homography from every tag corner found, each patch's median over "
	            "its centred %g x %g. Spread: 1.4826 x MAD of a patch's pixels, the largest "
	            "of any patch and channel. Error: the largest |detected - noise-free truth| "
	            "of any patch and channel, %% of full scale (the truth, "
	            "`fixtures/demo/<role>_chart_truth.cgats`, is what the session was rendered "
	            "from and includes the vignetting at the patch).\n\n",
	        d->layout_family, d->sample_fraction, d->sample_fraction);
	fprintf(fp, "| image | tags used | homography RMS (px) | patches | worst patch spread "
	            "| error vs truth | time |\n");
	fprintf(fp, "|---|---|---:|---:|---|---:|---:|\n");
	for (int k = 0; k < 2; k++) {
		const demo_chart_shot *sh = &d->shots[k];
		fprintf(fp, "| %s chart | %d (%s) | %.3f | %d of %d%s | %.4f (%s %c) | %.3f %% "
		            "| %.0f ms (decimate %d) |\n",
		        sh->role, sh->ntags_used, sh->tags_used, sh->rms_px, sh->nsampled,
		        sh->npatches, sh->nflagged ? " (some flagged)" : "", sh->worst_sd,
		        sh->worst_id, sh->worst_channel, sh->max_error, sh->detect_ms, sh->decimate);
	}
	fprintf(fp, "\n");
	fprintf(fp, "## Calibration\n\n");
	fprintf(fp, "- Method: **%s**, K = **%d** (uncentred PCA, %.4f of the chart's energy), "
	            "s = B M M2 rho.\n",
	        kg_method_name(cam->method), cam->K, ref->energy[ref->K - 1]);
	fprintf(fp, "- Reference chart: fit RMSE %.4f, leave-one-out RMSE %.4f, leave-one-out "
	            "dE00 %.2f (D65).\n",
	        map->fit_rmse, map->loo_rmse, map->loo_de00);
	fprintf(fp, "- M2 (site -> reference camera): condition number of M2 **%.3g**; of the "
	            "site chart rho_r %.3g (unit-RMS channels %.3g); residual %.2f %% of "
	            "||rho0||.\n",
	        d->cond_m2, cam->cond, cam->cond_equilibrated, 100.0 * cam->residual_relative);
	fprintf(fp, "- Cube: %ld object pixels judged against the truth; of all pixels %llu "
	            "flagged no data, %llu with negative bands clamped to 0.\n\n",
	        r->pixels, (unsigned long long)d->est_stats.nonfinite,
	        (unsigned long long)d->est_stats.clamped_pixels);

	fprintf(fp, "## Per material (the object's pixels, judged where they can be)\n\n");
	fprintf(fp, "Judged: the object's pixels at the incidence angles searched (%g-%g deg) "
	            "whose 3 x 3 neighbourhood is all of their material. Apart: the pixels at a "
	            "region's border, which the demosaicing of the raw frames (and the render's "
	            "pixel) mixes with the neighbour, and those seen beyond %g deg, outside the "
	            "searched range (mostly the rim's outer edge). Spectral RMSE of the estimate "
	            "against the material's reflectance at the pixel's own angle; the estimate "
	            "carries the light the pixel receives (the studio's level in its mirror "
	            "direction, 0.5-1, and the lobes), so also its least-squares scale onto the "
	            "truth, and the RMSE and dE00 (D65) after that scale; all averaged over the "
	            "judged pixels.\n\n",
	        d->angles[0], d->angles[1], d->angles[1]);
	fprintf(fp, "| # | material | region | judged pixels | mean angle | spectral RMSE | "
	            "scale | RMSE scaled | dE00 scaled (D65) | labelled correctly | at a border | "
	            "beyond %g deg (right) |\n",
	        d->angles[1]);
	fprintf(fp, "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
	for (int j = 0; j < r->n; j++) {
		const material_eval *m = &r->m[j];
		char region[32] = "-";
		if (m->region >= 0)
			demo_region_name(d->region_id[m->region], region, sizeof(region));
		if (!m->pixels && !m->mixed && !m->grazing) {
			fprintf(fp, "| %d | %s | %s | 0 | | | | | | | | |\n", j + 1, m->name, region);
			continue;
		}
		fprintf(fp, "| %d | %s | %s | %ld | %.1f | %.4f | %.2f | %.4f | %.2f | %.1f %% | %ld "
		            "| %ld (%.0f %%) |\n",
		        j + 1, m->name, region, m->pixels, m->angle, m->rmse, m->scale, m->srmse, m->de00,
		        m->pixels ? 100.0 * m->correct / m->pixels : 0.0, m->mixed, m->grazing,
		        m->grazing ? 100.0 * m->grazing_correct / m->grazing : 0.0);
	}
	fprintf(fp, "\n## Classification\n\n");
	fprintf(fp, "Classification accuracy: **%.2f %%** (%ld of %ld object pixels at %g-%g deg, "
	            "not at a border), camera-space matching among the %d materials of the "
	            "library, angle and intensity unknown (searched %g-%g deg, 0.3-1.0); a pixel "
	            "is right when its label holds its true material (a material, or a compound "
	            "class 'a|b' of materials the capture's noise cannot tell apart per pixel: "
	            "see `site/object/labels.json`, separability).\n\n",
	        r->pixels ? 100.0 * r->correct / r->pixels : 0.0, r->correct, r->pixels,
	        d->angles[0], d->angles[1], r->n, d->angles[0], d->angles[1]);
	fprintf(fp, "Counted apart: %ld object pixels at a region's border, mixed by the "
	            "demosaicing; %ld seen beyond %g deg (the rim's grazing edge, outside the "
	            "searched range), of which %.1f %% are labelled right. ",
	        r->mixed, r->grazing, d->angles[1],
	        r->grazing ? 100.0 * r->grazing_correct / r->grazing : 0.0);
	int bg_best = 0;
	for (int c = 1; c <= r->nclasses; c++)
		if (r->background_by_class[c] > r->background_by_class[bg_best])
			bg_best = c;
	fprintf(fp, "Not judged: the %ld pixels off the object, the studio's grey floor seen past "
	            "it, lit by the same light: %.1f %% of them are labelled '%s' (a neutral grey "
	            "under the light reads as silver, nearly as flat, does at a lower intensity, "
	            "within the searched range; the demo gives kogei process no object mask).\n\n",
	        r->background,
	        r->background ? 100.0 * r->background_by_class[bg_best] / r->background : 0.0,
	        bg_best < r->nclasses ? r->class_names[bg_best] : "(none)");
	fprintf(fp, "The label map's classes: ");
	for (int c = 0; c < r->nclasses; c++)
		fprintf(fp, "%s`%s`", c ? ", " : "", r->class_names[c]);
	fprintf(fp, ".\n\n");
	fprintf(fp, "Confusion matrix (rows: true material, columns: predicted, numbered as "
	            "above; a compound label counts on the diagonal when it holds the truth, "
	            "else under its first member%s):\n\n",
	        r->unclassified ? "; u: unclassified, unknown or background" : "");
	int ncol = r->n + (r->unclassified > 0);
	fprintf(fp, "| true \\ predicted |");
	for (int c = 0; c < ncol; c++)
		c < r->n ? fprintf(fp, " %d |", c + 1) : fprintf(fp, " u |");
	fprintf(fp, "\n|---|");
	for (int c = 0; c < ncol; c++)
		fprintf(fp, "---:|");
	fprintf(fp, "\n");
	for (int t = 0; t < r->n; t++) {
		if (!r->m[t].pixels)
			continue;
		fprintf(fp, "| %d %s |", t + 1, r->m[t].name);
		for (int c = 0; c < ncol; c++) {
			long v = r->confusion[(long)t * (r->n + 1) + (c < r->n ? c : r->n)];
			fprintf(fp, c == t ? " **%ld** |" : " %ld |", v);
		}
		fprintf(fp, "\n");
	}

	fprintf(fp, "\n## Regions\n\n");
	fprintf(fp, "The label map's regions (`site/object/labels_regions.csv`: connected pixels "
	            "of one class, decided on their pooled likelihood; a compound class resolved "
	            "into one member where the pooled posterior allows) of %d pixels or more: "
	            "**%d of %d** regions on the object have a label that holds their true "
	            "material (the majority of their object pixels), %d of them resolved to that "
	            "material alone. Not judged: %d mostly off the object, %d mostly beyond %g "
	            "deg.\n\n",
	        DEMO_REGION_MIN_PIXELS, r->nreg_right, r->nreg_judged, r->nreg_exact,
	        r->nreg_background, r->nreg_grazing, d->angles[1]);
	fprintf(fp, "| region | pixels | on the object | truth (share) | label | posterior | "
	            "verdict |\n|---:|---:|---:|---|---|---:|---|\n");
	for (int k = 0; k < r->nreg; k++) {
		const region_eval *g = &r->reg[k];
		const char *verdict = g->kind == REGION_BACKGROUND ? "not judged: off the object"
		                      : g->kind == REGION_GRAZING  ? "not judged: beyond the angles"
		                      : g->exact                   ? "right, resolved"
		                      : g->right                   ? "right"
		                                                   : "**wrong**";
		char truth[96] = "-";
		if (g->kind != REGION_BACKGROUND && g->truth >= 0)
			snprintf(truth, sizeof(truth), "%s (%.0f %%)", r->m[g->truth].name,
			         100.0 * g->votes[g->truth + 1] / g->object);
		fprintf(fp, "| %u | %ld | %.0f %% | %s | %s | %.3f | %s |\n", g->id, g->pixels,
		        100.0 * g->object / g->pixels, truth, g->label, g->posterior, verdict);
	}

	fprintf(fp, "\n## Re-render\n\n");
	fprintf(fp, "The object's scene rendered under D65 (%dx%d, %d samples per pixel, all 61 "
	            "bands; render/, Embree) once in each region's true material and once in the "
	            "material its estimated labels give: the majority label of the region's "
	            "judged pixels (among the labels that name materials); a compound label "
	            "renders as the member the label map's regions resolved most of those "
	            "pixels into, if they resolved more than they left compound, else as its "
	            "first member. Both renders share their random numbers, so where a region "
	            "kept its material the two agree but for light reflected from regions that "
	            "did not.\n\n",
	        DEMO_RERENDER_WIDTH, DEMO_RERENDER_HEIGHT, DEMO_RERENDER_SPP);
	fprintf(fp, "| region | true material | label (pixels) | rendered as | how |\n"
	            "|---|---|---|---|---|\n");
	for (int k = 0; k < d->nregions; k++) {
		char name[32];
		demo_region_name(d->region_id[k], name, sizeof(name));
		const material_eval *m = &r->m[d->region_material[k]];
		fprintf(fp, "| %s | %s | %s (%ld) | %s | %s |\n", name, m->name,
		        m->est_class >= 0 ? r->class_names[m->est_class] : "-", m->est_votes,
		        kg_material_library_get(d->lib, r->estimate_material[k])->name, m->est_how);
	}
	if (r->rr.available)
		fprintf(fp, "\nCIEDE2000 between the render from the truth and the re-render, over "
		            "the %ld object pixels: mean **%.2f**, 90th percentile **%.2f**, largest "
		            "%.1f (`rerender/de00.tif`, `truth_vs_estimate.png`).\n",
		        r->rr.pixels, r->rr.de00_mean, r->rr.de00_p90, r->rr.de00_max);
	else
		fprintf(fp, "\nRe-render skipped: kogei was built without Embree 3 "
		            "(libembree-dev).\n");

	fprintf(fp, "\n## Files\n\n"
	            "`truth_vs_estimate.png` (the truth's label map beside the estimated one; the "
	            "render from the truth beside the re-render from the labels and their dE00 "
	            "map), `spectra_by_material.png` (estimated against true spectra), "
	            "`confusion.png`, `object_d65.png` (camera image, true and estimated colour); "
	            "`rerender/` (the two scenes, their renders, the dE00 map); `lab/` and "
	            "`site/`, what kogei process wrote for each session (`reference.json`, "
	            "`camera.json`, `chart_overlay.png`, `process.json`, `report.html`, and "
	            "`site/object/` with the cube, the labels and their regions, the scene and "
	            "its render); the chart's measured spectra `chart_spectra.cgats`; the "
	            "sessions replayed (`lab-session/`, `site-session/`); the library's "
	            "`fig7_shibuichi-nami.csv`/`.png` and `materials_d65.png`. See docs/demo.md.\n");
}

static int summary(demo_ctx *d, const report *r)
{
	char *path = demo_path(d, "summary.md");
	char *text = NULL;
	size_t len = 0;
	kg_outfile out;
	FILE *mem = open_memstream(&text, &len);
	int ret = mem ? 0 : kg_fail(&d->err, KG_ENOMEM, "summary: out of memory");
	if (!ret) {
		write_summary(d, r, mem);
		if (fclose(mem) != 0)
			ret = kg_fail(&d->err, KG_ENOMEM, "summary: out of memory");
	}
	if (!ret)
		ret = kg_outfile_open(&out, path, 0, &d->err);
	if (!ret) {
		if (fwrite(text, 1, len, out.fp) != len) {
			kg_outfile_abort(&out);
			ret = kg_fail(&d->err, KG_EIO, "%s: write failed", path);
		} else {
			ret = kg_outfile_commit(&out, &d->err);
		}
	}
	if (!ret) {
		demo_wrote(d, path, "what was run and how well it did (below)");
		printf("\n%s", text);
	}
	free(text);
	free(path);
	return ret;
}

int demo_report(demo_ctx *d)
{
	report r = {0};
	int ret = evaluate(d, &r);
	if (!ret)
		ret = demo_rerender(d, r.estimate_material, &r.rr);
	if (!ret)
		ret = plot_truth_vs_estimate(d, &r);
	if (!ret)
		ret = plot_spectra(d, &r);
	if (!ret)
		ret = plot_confusion(d, &r);
	if (!ret)
		ret = plot_object(d, &r);
	if (!ret)
		ret = summary(d, &r);
	report_free(&r);
	return ret;
}
