/* Every sampled patch against the colour its layout expects there (docs/chart-detect.md,
 * "Patches against the layout's colours"): a patch covered by a card, painted over or
 * in a shadow of its own reads a colour that does not fit, and a step in the light
 * between patches (half the chart in shadow) makes a whole region read darker than its
 * colours predict, which the light field, fitted to each patch's own gradient, cannot
 * see.
 *
 * The model, for the patches with an expected colour e_i (linear RGB; the ColorChecker
 * 24's published colours):
 *   hue:   the measured colour's direction against M e_i, M the 3 x 3 matrix that maps
 *          the expected colours onto the measured ones best (chart_colour_fit: any
 *          camera primaries and white balance); the misfit is the sine of the angle;
 *   level: q_i = ln of the measured colour's scale along M e_i, against
 *          a + b ln Y_i + c x_i + d y_i (Y_i the expected luminance: b takes a tone
 *          curve such as a JPEG's; c, d a light gradient the light field left), and,
 *          in the step search, + s [i on one side of a line].
 * Each misfit is divided by the patch's tolerance (tol_hue, tol_level: larger for
 * saturated colours, which a 3 x 3 matrix maps less exactly, and for dark patches,
 * where flare and the black level weigh), and a patch is flagged when either exceeds
 * the threshold: MISFIT_SPREAD times the chart's own robust spread (1.4826 x the median
 * over its patches) within MISFIT_MIN..MISFIT_MAX, so a chart whose colours fit the
 * model less well (narrow-band channels, a camera's tone curve) is judged by its own
 * scatter. The fit is robust: a first fit on every patch, three fits on the
 * three quarters that fit it best (concentration steps), then the patches within the
 * threshold refitted until the set stays the same. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

/* fewest patches with an expected colour for the check to run */
#define MIN_PATCHES 12
/* tolerances (ln level; sine of the hue angle): a neutral mid-level patch, the extra
 * for a colour's chroma (sine of its angle from neutral), and an offset of this
 * fraction of a white of luminance 1 (flare, black level) at the patch's luminance.
 * Derived from real photographs and simulated ones (docs/chart-detect.md). */
#define TOL_LEVEL 0.05
#define TOL_LEVEL_CHROMA 0.3
#define TOL_LEVEL_OFFSET 0.006
#define TOL_HUE 0.03
#define TOL_HUE_OFFSET 0.004
#define MISFIT_MIN 4.5
#define MISFIT_SPREAD 5.0
#define MISFIT_MAX 10.0
/* patches whose hues miss the layout's by more than this sine at the median are not
 * the layout's chart (a chart of one's own with ColorChecker ids): not judged. Real
 * ColorCheckers: 0.013-0.067 (a camera JPEG the largest) */
#define NOT_THE_COLOURS 0.15
/* the measured colours' spread (RMS sine from their mean direction) below which the
 * picture has no colour to judge: the tagless detector's, KG_ORIENT_SPREAD_MIN */
#define KG_CHART_COLOUR_SPREAD_MIN 0.05
/* the step search: lines at this many directions over 180 degrees, each side holding
 * STEP_MIN_SIDE patches at least */
#define STEP_DIRECTIONS 12
#define STEP_MIN_SIDE 3
#define STEP_LOSS_RATIO 0.25
#define STEP_LOSS_DROP 1.0
enum { NTERMS = 5 }; /* level: offset, tone, [x, y], [step] */

typedef struct cpatch {
	int index;          /* in the result's patches */
	double m[3], u[3];  /* measured colour, its direction */
	double e[3], eu[3]; /* expected colour (linear), its direction */
	double lny, x, y;   /* ln expected luminance; position, about -1..1 */
	double tol_level, tol_hue;
	int side;           /* of the step line being tried */
	/* from the current fit */
	double q, hue, level, score;
} cpatch;

typedef struct cfit {
	double M[9];
	double c[NTERMS];
	double t_level, t_hue; /* thresholds, in tolerance units */
	int keep_thresholds;   /* 1: t_level, t_hue as they are (the step fits: the flat
	                        * fit's, so the losses compare) */
	int nout;              /* patches with score > 1 */
	double loss;           /* sum of min(score^2, 1): outliers count 1 */
} cfit;

typedef struct cwork {
	cpatch *p;
	int n;
	int plane; /* the level model has a plane in x, y: no light field was removed */
	int *act, *order;
	double *s, (*u)[3], (*eu)[3], *tmp;
} cwork;

/* The layout's expected colours (linear RGB) where it has them: the ColorChecker 24's
 * published ones for a layout of its 24 patches. 0: none. */
static int expected_colours(const kg_chart_layout *l, double (*lin)[3], int *have)
{
	int idx[24];
	for (int i = 0; i < l->npatches; i++)
		have[i] = 0;
	if (!chart_colorchecker24_patches(l, idx))
		return 0;
	for (int k = 0; k < 24; k++) {
		chart_cc24_linear(k, lin[idx[k]]);
		have[idx[k]] = 1;
	}
	return 24;
}

/* The threshold for the patches' level (hue) misfits in tolerance units: MISFIT_SPREAD
 * times their robust spread, within MISFIT_MIN..MISFIT_MAX (the median breaks down
 * when half the chart is off: in a shadow). */
static double threshold(const cwork *w, int level)
{
	for (int i = 0; i < w->n; i++)
		w->tmp[i] = level ? w->p[i].level : w->p[i].hue;
	return fmin(MISFIT_MAX, fmax(MISFIT_MIN, MISFIT_SPREAD * 1.4826 * calib_median(w->tmp, w->n)));
}

/* The level model's terms at patch p (the step's last); their number. */
static int level_terms(const cwork *w, const cpatch *p, int step, double a[NTERMS])
{
	int m = 0;
	a[m++] = 1;
	a[m++] = p->lny;
	if (w->plane) {
		a[m++] = p->x;
		a[m++] = p->y;
	}
	if (step)
		a[m++] = p->side;
	return m;
}

/* The level model's prediction at p, without its step. */
static double level_predicted(const cwork *w, const cpatch *p, const double c[NTERMS])
{
	double a[NTERMS], pred = 0;
	int m = level_terms(w, p, 0, a);
	for (int j = 0; j < m; j++)
		pred += c[j] * a[j];
	return pred;
}

/* Weighted least squares of the level model over the active patches; KG_EINVAL when
 * the terms are not determined (a step side with no active patch). */
static int fit_level(const cwork *w, const int *act, int step, double c[NTERMS])
{
	double N[NTERMS][NTERMS] = {{0}}, b[NTERMS] = {0}, a[NTERMS];
	int m = level_terms(w, &w->p[0], step, a), k = 0;
	for (int i = 0; i < w->n; i++) {
		if (!act[i])
			continue;
		double wt = 1 / (w->p[i].tol_level * w->p[i].tol_level);
		level_terms(w, &w->p[i], step, a);
		for (int j = 0; j < m; j++) {
			b[j] += wt * a[j] * w->p[i].q;
			for (int l = 0; l < m; l++)
				N[j][l] += wt * a[j] * a[l];
		}
		k++;
	}
	for (int j = 0; j < NTERMS; j++)
		c[j] = 0;
	if (k < m + 2 || calib_solve_normal(&N[0][0], NTERMS, b, m, c))
		return KG_EINVAL;
	return 0;
}

/* Each patch's hue misfit and level q (through f->M; kept when fixed_hue), its misfit
 * against the level model, the thresholds and scores. */
static void score(cwork *w, int step, cfit *f, const int *act, int fixed_hue)
{
	for (int i = 0; !fixed_hue && i < w->n; i++) { /* M kept: hue and q are as they were */
		cpatch *p = &w->p[i];
		double pm[3], pp = 0, mp = 0;
		for (int r = 0; r < 3; r++) {
			pm[r] = f->M[3 * r] * p->e[0] + f->M[3 * r + 1] * p->e[1] + f->M[3 * r + 2] * p->e[2];
			pp += pm[r] * pm[r];
			mp += p->m[r] * pm[r];
		}
		p->hue = sqrt(chart_colour_sin2(f->M, p->eu, p->u)) / p->tol_hue;
		p->q = mp > 0 && pp > 0 ? log(mp / pp) : -50;
	}
	if (act && fit_level(w, act, step, f->c))
		f->c[0] = NAN;
	for (int i = 0; i < w->n; i++) {
		cpatch *p = &w->p[i];
		double a[NTERMS], pred = 0;
		int m = level_terms(w, p, step, a);
		for (int j = 0; j < m; j++)
			pred += f->c[j] * a[j];
		p->level = fabs(p->q - pred) / p->tol_level;
		if (!isfinite(p->level))
			p->level = INFINITY;
	}
	if (!f->keep_thresholds) {
		f->t_level = threshold(w, 1);
		f->t_hue = threshold(w, 0);
	}
	f->nout = 0;
	f->loss = 0;
	for (int i = 0; i < w->n; i++) {
		cpatch *p = &w->p[i];
		p->score = fmax(p->level / f->t_level, p->hue / f->t_hue);
		f->nout += !(p->score <= 1);
		f->loss += p->score <= 1 ? p->score * p->score : 1;
	}
}

/* One fit: M (unless fixed) and the level model over act, then the scores. */
static int fit_once(cwork *w, const int *act, int step, int fixed_hue, cfit *f)
{
	if (!fixed_hue) {
		int k = 0;
		for (int i = 0; i < w->n; i++)
			k += act[i];
		if (k < MIN_PATCHES / 2 ||
		    chart_colour_fit(w->n, (const double (*)[3])w->u, (const double (*)[3])w->eu, act,
		                     w->s, f->M) >= 1)
			return KG_EINVAL;
	}
	score(w, step, f, act, fixed_hue);
	return isfinite(f->c[0]) ? 0 : KG_EINVAL;
}

/* act: the k patches of lowest score. */
static void lowest(cwork *w, int k)
{
	int *order = w->order;
	for (int i = 0; i < w->n; i++)
		order[i] = i;
	for (int i = 1; i < w->n; i++)
		for (int j = i; j > 0 && w->p[order[j - 1]].score > w->p[order[j]].score; j--) {
			int t = order[j];
			order[j] = order[j - 1];
			order[j - 1] = t;
		}
	for (int i = 0; i < w->n; i++)
		w->act[i] = 0;
	for (int i = 0; i < k; i++)
		w->act[order[i]] = 1;
}

/* The robust fit (the file's comment): f and each patch's scores; w->act the patches
 * it rests on. KG_EINVAL when the model cannot be fitted. */
static int robust_fit(cwork *w, int step, int fixed_hue, cfit *f)
{
	int n = w->n, ret;
	for (int i = 0; i < n; i++)
		w->act[i] = 1;
	if ((ret = fit_once(w, w->act, step, fixed_hue, f)))
		return ret;
	for (int round = 0; round < 3; round++) {
		lowest(w, (3 * n + 3) / 4);
		if ((ret = fit_once(w, w->act, step, fixed_hue, f)))
			return ret;
	}
	for (int round = 0; round < 8; round++) {
		int changed = 0, k = 0;
		for (int i = 0; i < n; i++)
			k += w->p[i].score <= 1;
		if (k < (n + 1) / 2) {
			lowest(w, (n + 1) / 2);
			changed = 1;
		} else {
			for (int i = 0; i < n; i++) {
				int a = w->p[i].score <= 1;
				changed |= a != w->act[i];
				w->act[i] = a;
			}
		}
		if (!changed)
			break;
		if ((ret = fit_once(w, w->act, step, fixed_hue, f)))
			return ret;
	}
	return 0;
}

/* Where on the chart a group of patches lies, as seen on the layout: "left",
 * "top right", ... from the direction (dx, dy) of its centre from the others'. */
static const char *where(double dx, double dy)
{
	static const char *const names[8] = {"right",      "bottom right", "bottom", "bottom left",
	                                     "left",       "top left",     "top",    "top right"};
	double a = atan2(dy, dx); /* y down */
	int k = (int)floor(a / (M_PI / 4) + 0.5);
	return names[(k % 8 + 8) % 8];
}

/* The best step line: the one whose fit (M and the thresholds kept) leaves the
 * smallest loss; its sides in w->p[].side, its step (ln of the light on side 1 over
 * side 0) in *s, its loss in *loss. 0 when no line was fitted. */
static int best_step(cwork *w, const cfit *flat, double *s, double *loss)
{
	int n = w->n, found = 0;
	int *best_side = malloc((size_t)n * sizeof(*best_side));
	double *proj = malloc((size_t)n * sizeof(*proj));
	if (!best_side || !proj) {
		free(best_side);
		free(proj);
		return 0;
	}
	for (int k = 0; k < STEP_DIRECTIONS; k++) {
		double th = M_PI * k / STEP_DIRECTIONS, nx = cos(th), ny = sin(th);
		for (int i = 0; i < n; i++)
			proj[i] = w->p[i].x * nx + w->p[i].y * ny;
		for (int i = 0; i < n; i++) {
			/* the line just past patch i's projection (patches within 1e-6 alike) */
			double t = proj[i] + 1e-6;
			int na = 0, dup = 0;
			for (int j = 0; j < n; j++)
				na += (w->p[j].side = proj[j] < t);
			for (int j = 0; j < i && !dup; j++) /* the same split as an earlier patch's */
				dup = fabs(proj[j] - proj[i]) < 1e-6;
			if (dup || na < STEP_MIN_SIDE || n - na < STEP_MIN_SIDE)
				continue;
			cfit f = *flat;
			f.keep_thresholds = 1;
			if (robust_fit(w, 1, 1, &f) || (found && !(f.loss < *loss)))
				continue;
			found = 1;
			*loss = f.loss;
			double a[NTERMS];
			*s = f.c[level_terms(w, &w->p[0], 1, a) - 1];
			for (int j = 0; j < n; j++)
				best_side[j] = w->p[j].side;
		}
	}
	for (int j = 0; found && j < n; j++)
		w->p[j].side = best_side[j];
	free(best_side);
	free(proj);
	return found;
}

/* A step is the light's, not a few odd patches' or a gradient's: larger than the
 * level threshold of a neutral patch, and explaining most of what the fit without it
 * leaves (its loss STEP_LOSS_RATIO of that or less, and STEP_LOSS_DROP less: one
 * outlier's worth). */
static int is_step(const cfit *flat, double s, double loss)
{
	return fabs(s) > flat->t_level * TOL_LEVEL && loss <= STEP_LOSS_RATIO * flat->loss &&
	       flat->loss - loss >= STEP_LOSS_DROP;
}

static int refuse_step(const kg_chart_result *r, const cwork *w, double s, kg_err *err)
{
	int n = w->n, dark = s < 0 ? 1 : 0, nd = 0;
	double cd[2] = {0, 0}, cb[2] = {0, 0};
	char ids[400] = "";
	size_t at = 0;
	for (int i = 0; i < n; i++) {
		const cpatch *p = &w->p[i];
		int d = p->side == dark;
		double *c = d ? cd : cb;
		c[0] += p->x;
		c[1] += p->y;
		nd += d;
		if (d && at < sizeof(ids) - 1)
			at += (size_t)snprintf(ids + at, sizeof(ids) - at, "%s%s", at ? ", " : "",
			                       r->patches[p->index].id);
	}
	double dx = cd[0] / nd - cb[0] / (n - nd), dy = cd[1] / nd - cb[1] / (n - nd);
	const char *to = where(dx, dy), *from = where(-dx, -dy);
	double frac = (double)nd / n;
	return kg_fail(err, KG_EINVAL,
	               "the light over chart %s falls by %.0f %% from its %s to its %s %s, a "
	               "step between patches: %d of its %d patches (%s) read %.2f x the level "
	               "their colours predict from the others' (judged against the layout's "
	               "colours); the light field, fitted to each patch's own gradient, cannot "
	               "see a step between patches, so it is not corrected. A shadow, a second "
	               "light or the edge of a lamp's beam? Light the chart evenly",
	               r->layout, 100 * (1 - exp(-fabs(s))), from, to,
	               frac > 0.35 && frac < 0.65 ? "half" : "part", nd, n, ids, exp(-fabs(s)));
}

/* The reason written into a patch's warning. */
static void flag_patch(const cwork *w, kg_chart_sample *s, const cpatch *p, const cfit *f)
{
	double ratio = exp(p->q - level_predicted(w, p, f->c));
	double deg = asin(fmin(1, p->hue * p->tol_hue)) * 180 / M_PI;
	s->flags |= KG_CHART_FLAG_MISFIT;
	size_t at = strlen(s->warning);
	snprintf(s->warning + at, sizeof(s->warning) - at,
	         "%scolour does not fit the layout's (%.2f x the level its colour predicts "
	         "from the other patches', hue %.0f degrees off; %.1f x the threshold): "
	         "covered, painted over or in a shadow?",
	         at ? "; " : "", ratio, deg, p->score);
}

static void record(kg_chart_result *r, const cwork *w, const cfit *f)
{
	kg_chart_colour_check *c = &r->colours;
	c->checked = 1;
	c->used = w->n;
	c->threshold_level = f->t_level;
	c->threshold_hue = f->t_hue;
	c->worst = 0;
	c->worst_id[0] = '\0';
	for (int i = 0; i < w->n; i++) {
		const cpatch *p = &w->p[i];
		r->patches[p->index].misfit = p->score;
		if (p->score > 1) {
			c->flagged++;
		} else if (p->score >= c->worst) {
			c->worst = p->score;
			snprintf(c->worst_id, sizeof(c->worst_id), "%s", r->patches[p->index].id);
		}
	}
}

/* The patches that take part: an expected colour, no flag, a value above zero. */
static int gather(const kg_chart_result *r, const double (*lin)[3], const int *have,
                  cpatch *p)
{
	double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
	int n = 0;
	for (int i = 0; i < r->npatches; i++) {
		const kg_chart_sample *s = &r->patches[i];
		if (!have[i] || s->flags || !(s->rgb[0] > 0 && s->rgb[1] > 0 && s->rgb[2] > 0) ||
		    !isfinite(s->rgb[0] + s->rgb[1] + s->rgb[2]))
			continue;
		cpatch *q = &p[n++];
		memset(q, 0, sizeof(*q));
		q->index = i;
		memcpy(q->m, s->rgb, sizeof(q->m));
		chart_unit3(q->m, q->u);
		memcpy(q->e, lin[i], sizeof(q->e));
		chart_unit3(q->e, q->eu);
		double Y = 0.2126 * q->e[0] + 0.7152 * q->e[1] + 0.0722 * q->e[2];
		double grey = (q->eu[0] + q->eu[1] + q->eu[2]) / sqrt(3.0);
		double chroma = sqrt(fmax(0, 1 - grey * grey));
		Y = fmax(Y, 1e-3);
		q->lny = log(Y);
		q->tol_level = sqrt(TOL_LEVEL * TOL_LEVEL + pow(TOL_LEVEL_CHROMA * chroma, 2) +
		                    pow(TOL_LEVEL_OFFSET / Y, 2));
		q->tol_hue = sqrt(TOL_HUE * TOL_HUE + pow(TOL_HUE_OFFSET / Y, 2));
		q->x = s->centre_mm[0];
		q->y = s->centre_mm[1];
		x0 = fmin(x0, q->x);
		x1 = fmax(x1, q->x);
		y0 = fmin(y0, q->y);
		y1 = fmax(y1, q->y);
	}
	double sc = fmax(1e-9, 0.5 * fmax(x1 - x0, y1 - y0));
	for (int i = 0; i < n; i++) {
		p[i].x = (p[i].x - 0.5 * (x0 + x1)) / sc;
		p[i].y = (p[i].y - 0.5 * (y0 + y1)) / sc;
	}
	return n;
}

static void work_free(cwork *w)
{
	free(w->p);
	free(w->act);
	free(w->order);
	free(w->s);
	free(w->u);
	free(w->eu);
	free(w->tmp);
}

int chart_check_colours(const kg_chart_layout *l, kg_chart_result *r, kg_err *err)
{
	memset(&r->colours, 0, sizeof(r->colours));
	for (int i = 0; i < r->npatches; i++)
		r->patches[i].misfit = NAN;
	size_t np = r->npatches > 0 ? (size_t)r->npatches : 1;
	double (*lin)[3] = malloc(np * sizeof(*lin));
	int *have = malloc(np * sizeof(*have));
	cwork w = {0};
	w.p = malloc(np * sizeof(*w.p));
	w.act = malloc(np * sizeof(*w.act));
	w.order = malloc(np * sizeof(*w.order));
	w.s = malloc(np * sizeof(*w.s));
	w.u = malloc(np * sizeof(*w.u));
	w.eu = malloc(np * sizeof(*w.eu));
	w.tmp = malloc(np * sizeof(*w.tmp));
	int ret = 0;
	if (!lin || !have || !w.p || !w.act || !w.order || !w.s || !w.u || !w.eu || !w.tmp) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto done;
	}
	if (r->npatches != l->npatches || !expected_colours(l, lin, have))
		goto done;
	w.n = gather(r, (const double (*)[3])lin, have, w.p);
	/* the light field removed, what it leaves is not a gradient to fit */
	w.plane = !r->light.fitted;
	if (w.n < MIN_PATCHES) {
		snprintf(r->colours.note, sizeof(r->colours.note), "not judged: %d patches with an "
		         "expected colour and no other flag, %d needed", w.n, MIN_PATCHES);
		goto done;
	}
	for (int i = 0; i < w.n; i++) {
		memcpy(w.u[i], w.p[i].u, sizeof(w.u[i]));
		memcpy(w.eu[i], w.p[i].eu, sizeof(w.eu[i]));
		w.act[i] = 1;
	}
	/* a grey picture (one channel, or a camera without colour) fits any colours */
	double spread = chart_direction_spread(w.n, (const double (*)[3])w.u, w.act);
	if (!(spread > KG_CHART_COLOUR_SPREAD_MIN)) {
		snprintf(r->colours.note, sizeof(r->colours.note), "not judged: the patches have "
		         "next to no colour (spread %.3f, a sine; %.2f needed)", spread,
		         KG_CHART_COLOUR_SPREAD_MIN);
		goto done;
	}
	cfit flat;
	memset(&flat, 0, sizeof(flat));
	if (robust_fit(&w, 0, 0, &flat))
		goto done; /* the colours cannot be fitted: nothing is judged */
	for (int i = 0; i < w.n; i++)
		w.tmp[i] = w.p[i].hue * w.p[i].tol_hue;
	double hue = calib_median(w.tmp, w.n);
	if (!(hue <= NOT_THE_COLOURS)) {
		snprintf(r->colours.note, sizeof(r->colours.note), "not judged: the patches' colours "
		         "do not read as the layout's (median hue misfit %.2f, a sine; above %.2f)",
		         hue, NOT_THE_COLOURS);
		goto done;
	}
	cpatch *keep = malloc((size_t)w.n * sizeof(*keep));
	if (!keep) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto done;
	}
	memcpy(keep, w.p, (size_t)w.n * sizeof(*keep));
	double s = 0, loss = 0;
	int stepped = best_step(&w, &flat, &s, &loss);
	if (stepped && is_step(&flat, s, loss)) {
		ret = refuse_step(r, &w, s, err);
		free(keep);
		goto done;
	}
	memcpy(w.p, keep, (size_t)w.n * sizeof(*keep));
	free(keep);
	for (int i = 0; i < w.n; i++)
		if (w.p[i].score > 1)
			flag_patch(&w, &r->patches[w.p[i].index], &w.p[i], &flat);
	record(r, &w, &flat);
done:
	free(lin);
	free(have);
	work_free(&w);
	return ret;
}
