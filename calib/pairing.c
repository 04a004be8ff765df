/* Pairing two patch files of one chart by SAMPLE_ID, checked by colour: a file of
 * known colours (the spectra's XYZ, or the reference camera's rho0) and a camera's
 * values of the same patches must be one 3 x 3 matrix apart. Ids that name other
 * patches (another numbering convention, two swapped rows) are refused with what each
 * file's ids look like and the re-pairing that fits, if any (kg_calib.h: the limits
 * and the measurements behind them). */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib_private.h"

/* Each patch's error is relative to its own colour plus this fraction of the
 * brightest patch's: dark patches carry the camera's noise and the lens's flare. */
#define PAIR_FLOOR 0.05
/* The robust fit tries every triple of patches up to this many, else as many triples
 * drawn by a fixed sequence. */
#define PAIR_MAX_TRIPLES 4000
/* The single-patch check (an n x n assignment) is skipped above this many pairs. */
#define PAIR_MAX_ASSIGN 600

static double dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* ---- names of the pairings ----------------------------------------------------- */

void kg_id_pairing_name(kg_id_pairing p, const char *first, const char *second, char *buf,
                        size_t size)
{
	static const char *const names[KG_ID_PAIRING_COUNT] = {
		"names", "file-order", "grid-order", "%s-by-number", "%s-by-number",
		"number+1", "number-1", "letter+1", "letter-1",
	};
	if (p < 0 || p >= KG_ID_PAIRING_COUNT) {
		snprintf(buf, size, "unknown");
		return;
	}
	snprintf(buf, size, names[p], p == KG_ID_PAIRING_SECOND_BY_NUMBER ? second : first);
}

int kg_id_pairing_parse(const char *name, const char *first, const char *second,
                        kg_id_pairing *out, kg_err *err)
{
	char list[400] = "", one[64];
	for (int p = 0; p < KG_ID_PAIRING_COUNT; p++) {
		kg_id_pairing_name((kg_id_pairing)p, first, second, one, sizeof(one));
		if (name && strcmp(name, one) == 0) {
			*out = (kg_id_pairing)p;
			return 0;
		}
		size_t at = strlen(list);
		snprintf(list + at, sizeof(list) - at, "%s%s", p ? ", " : "", one);
	}
	return kg_fail(err, KG_EINVAL, "id pairing '%s': expected one of %s", name ? name : "",
	               list);
}

void kg_pairing_record_free(kg_pairing_record *rec)
{
	if (!rec)
		return;
	for (int s = 0; s < 2; s++)
		calib_strv_free(rec->unpaired[s], rec->nunpaired[s]);
	memset(rec, 0, sizeof(*rec));
	rec->misfit = NAN;
}

/* ---- the sides ------------------------------------------------------------------ */

int calib_pair_side_new(const char *file, const char *role, const char *what,
                        char *const *ids, int n, const double (*colour)[3],
                        calib_pair_side *s, kg_err *err)
{
	*s = (calib_pair_side){file, role, what, ids, n, NULL, NULL};
	s->colour = malloc((n > 0 ? (size_t)n : 1) * sizeof(*s->colour));
	s->skip = calloc(n > 0 ? (size_t)n : 1, 1);
	if (!s->colour || !s->skip) {
		calib_pair_side_free(s);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	memcpy(s->colour, colour, (size_t)n * sizeof(*s->colour));
	return 0;
}

void calib_pair_side_skip(calib_pair_side *s, const char *const *exclude, int nexclude,
                          const kg_patchset *camera, double clip)
{
	int flags = camera ? kg_patchset_extra_index(camera, "FLAGS") : -1;
	int stride = 0;
	const double *clipped = camera ? calib_clipped_column(camera, &stride) : NULL;
	for (int i = 0; i < s->n; i++) {
		for (int e = 0; e < nexclude; e++)
			s->skip[i] |= strcmp(exclude[e], s->ids[i]) == 0;
		if (flags >= 0)
			s->skip[i] |= camera->extra[(size_t)i * camera->nextra + flags] != 0;
		/* clipping judged on the sensor's codes when the file says (a value above
		 * clip after a light-field or flat correction is not clipped), else on the
		 * values */
		if (clipped)
			s->skip[i] |= clipped[(size_t)i * stride] > 0;
		for (int c = 0; camera && c < 3; c++)
			s->skip[i] |= (!clipped && camera->rgb[i][c] >= clip) || camera->rgb[i][c] <= 0;
	}
}

void calib_pair_side_free(calib_pair_side *s)
{
	free(s->colour);
	free(s->skip);
	s->colour = NULL;
	s->skip = NULL;
}

/* ---- ids as a grid ------------------------------------------------------------- */

/* An id's place: "A01", "a1", "A0" -> letter 1 (A), number; "7" -> letter 0, number 7.
 * 0 for anything else (two letters, a suffix, a sign). */
static int id_place(const char *id, int *letter, long *number)
{
	const char *p = id;
	*letter = 0;
	if (isalpha((unsigned char)*p))
		*letter = toupper((unsigned char)*p++) - 'A' + 1;
	if (!isdigit((unsigned char)*p))
		return 0;
	char *end;
	*number = strtol(p, &end, 10);
	return *end == 0 && *number <= 100000;
}

/* All ids of a file placed, with one shape (all lettered or all plain numbers) and no
 * two on one place. */
static int grid_of(const calib_pair_side *s, int *letter, long *number)
{
	for (int i = 0; i < s->n; i++) {
		if (!id_place(s->ids[i], &letter[i], &number[i]) || (letter[i] > 0) != (letter[0] > 0))
			return 0;
		for (int j = 0; j < i; j++)
			if (letter[j] == letter[i] && number[j] == number[i])
				return 0;
	}
	return s->n > 0;
}

typedef struct place {
	long major, minor;
	int index;
} place;

static int place_cmp(const void *pa, const void *pb)
{
	const place *a = pa, *b = pb;
	if (a->major != b->major)
		return a->major < b->major ? -1 : 1;
	return a->minor < b->minor ? -1 : a->minor > b->minor;
}

/* The file's patch indices in grid order: by letter then number, or (by_number) by
 * number then letter. 0 when its ids are not a grid. */
static int grid_order(const calib_pair_side *s, int by_number, int *order)
{
	int *letter = malloc((size_t)s->n * sizeof(int));
	long *number = malloc((size_t)s->n * sizeof(long));
	place *pl = malloc((size_t)s->n * sizeof(place));
	int ok = letter && number && pl && grid_of(s, letter, number);
	for (int i = 0; ok && i < s->n; i++)
		pl[i] = by_number ? (place){number[i], letter[i], i} : (place){letter[i], number[i], i};
	if (ok) {
		qsort(pl, (size_t)s->n, sizeof(place), place_cmp);
		for (int i = 0; i < s->n; i++)
			order[i] = pl[i].index;
	}
	free(letter);
	free(number);
	free(pl);
	return ok;
}

/* The first file's (letter, number) moved by (dl, dn) in the second. */
static int shifted(const calib_pair_side *a, const calib_pair_side *b, int dl, long dn,
                   int *map)
{
	int *la = malloc((size_t)(a->n + b->n) * sizeof(int)), *lb = la + a->n;
	long *na = malloc((size_t)(a->n + b->n) * sizeof(long)), *nb = na + a->n;
	int count = 0;
	if (la && na && grid_of(a, la, na) && grid_of(b, lb, nb) && (dl == 0 || la[0] > 0))
		for (int i = 0; i < a->n; i++)
			for (int j = 0; j < b->n && map[i] < 0; j++)
				if (lb[j] == la[i] + dl && nb[j] == na[i] + dn) {
					map[i] = j;
					count++;
				}
	free(la);
	free(na);
	return count;
}

int calib_pair_map(const calib_pair_side *a, const calib_pair_side *b, kg_id_pairing how,
                   int *map, const char **alias)
{
	*alias = NULL;
	for (int i = 0; i < a->n; i++)
		map[i] = -1;
	if (how == KG_ID_PAIRING_NAMES)
		return kg_patch_ids_match(a->ids, a->n, b->ids, b->n, map, alias);
	if (how >= KG_ID_PAIRING_NUMBER_UP) {
		static const int dl[4] = {0, 0, 1, -1}, dn[4] = {1, -1, 0, 0};
		int k = how - KG_ID_PAIRING_NUMBER_UP;
		return shifted(a, b, dl[k], dn[k], map);
	}
	int *oa = malloc((size_t)a->n * sizeof(int)), *ob = malloc((size_t)b->n * sizeof(int));
	if (!oa || !ob) {
		free(oa);
		free(ob);
		return -1;
	}
	int ok = 1;
	if (how == KG_ID_PAIRING_FILE_ORDER) {
		for (int i = 0; i < a->n; i++)
			oa[i] = i;
		for (int j = 0; j < b->n; j++)
			ob[j] = j;
	} else {
		ok = grid_order(a, how == KG_ID_PAIRING_FIRST_BY_NUMBER, oa) &&
		     grid_order(b, how == KG_ID_PAIRING_SECOND_BY_NUMBER, ob);
	}
	int n = ok ? (a->n < b->n ? a->n : b->n) : 0;
	for (int k = 0; k < n; k++)
		map[oa[k]] = ob[k];
	free(oa);
	free(ob);
	return n;
}

/* A grid's size: letters (0 for plain numbers) and numbers it spans. */
static int grid_shape(const calib_pair_side *s, int *letters, long *numbers)
{
	int *letter = malloc((size_t)s->n * sizeof(int));
	long *number = malloc((size_t)s->n * sizeof(long));
	int ok = letter && number && grid_of(s, letter, number);
	int l0 = ok ? letter[0] : 0, l1 = l0;
	long n0 = ok ? number[0] : 0, n1 = n0;
	for (int i = 1; ok && i < s->n; i++) {
		l0 = letter[i] < l0 ? letter[i] : l0;
		l1 = letter[i] > l1 ? letter[i] : l1;
		n0 = number[i] < n0 ? number[i] : n0;
		n1 = number[i] > n1 ? number[i] : n1;
	}
	*letters = l0 > 0 ? l1 - l0 + 1 : 0;
	*numbers = n1 - n0 + 1;
	free(letter);
	free(number);
	return ok;
}

/* How a file names its patches: "A01..D06 (4 letters A-D x 6 numbers 1-6)", "1..24
 * (plain numbers)", or its first and last ids when they are not a grid; and when the
 * other file's grid has its letters and numbers the other way round, that too. */
static void describe_ids(const calib_pair_side *s, const calib_pair_side *other, char *buf,
                         size_t size)
{
	int *order = malloc((size_t)s->n * sizeof(int)), *letter = malloc((size_t)s->n * sizeof(int));
	long *number = malloc((size_t)s->n * sizeof(long));
	int lo, ls;
	long no, ns;
	if (!order || !letter || !number || !grid_order(s, 0, order) ||
	    !grid_of(s, letter, number)) {
		snprintf(buf, size, "%s..%s (not a letter-and-number grid)", s->ids[0],
		         s->ids[s->n - 1]);
	} else {
		int l0 = letter[order[0]], l1 = letter[order[s->n - 1]];
		long n0 = number[0], n1 = number[0];
		for (int i = 1; i < s->n; i++) {
			n0 = number[i] < n0 ? number[i] : n0;
			n1 = number[i] > n1 ? number[i] : n1;
		}
		const char *first = s->ids[order[0]], *last = s->ids[order[s->n - 1]];
		const char *from = n0 == 0 ? ", counted from 0" : "";
		int turned = other && grid_shape(s, &ls, &ns) && grid_shape(other, &lo, &no) && ls > 0 &&
		             ls != ns && ls == no && ns == lo;
		if (l0 == 0)
			snprintf(buf, size, "%s..%s (plain numbers%s)", first, last, from);
		else
			snprintf(buf, size, "%s..%s (%d letters %c-%c x %ld numbers %ld-%ld%s%s)", first,
			         last, l1 - l0 + 1, 'A' + l0 - 1, 'A' + l1 - 1, n1 - n0 + 1, n0, n1, from,
			         turned ? ": the other file's grid turned, letters for its numbers" : "");
	}
	free(order);
	free(letter);
	free(number);
}

/* ---- the colour fit ------------------------------------------------------------- */

/* The pairs judged by colour: known colour t, camera value c, and where each came
 * from. */
typedef struct pairs {
	int n;
	double (*t)[3], (*c)[3];
	int *ia, *ib;
	double floor2; /* (PAIR_FLOOR x the brightest known colour)^2 */
} pairs;

static void pairs_free(pairs *p)
{
	free(p->t);
	free(p->c);
	free(p->ia);
	free(p->ib);
	memset(p, 0, sizeof(*p));
}

static int usable(const calib_pair_side *s, int i)
{
	const double *v = s->colour[i];
	return !s->skip[i] && isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static int pairs_from(const calib_pair_side *a, const calib_pair_side *b, const int *map,
                      pairs *p)
{
	memset(p, 0, sizeof(*p));
	size_t n = a->n > 0 ? (size_t)a->n : 1;
	p->t = malloc(n * sizeof(*p->t));
	p->c = malloc(n * sizeof(*p->c));
	p->ia = malloc(n * sizeof(int));
	p->ib = malloc(n * sizeof(int));
	if (!p->t || !p->c || !p->ia || !p->ib) {
		pairs_free(p);
		return -1;
	}
	double top = 0;
	for (int i = 0; i < a->n; i++) {
		if (map[i] < 0 || !usable(a, i) || !usable(b, map[i]))
			continue;
		memcpy(p->t[p->n], a->colour[i], sizeof(p->t[0]));
		memcpy(p->c[p->n], b->colour[map[i]], sizeof(p->c[0]));
		p->ia[p->n] = i;
		p->ib[p->n] = map[i];
		top = fmax(top, sqrt(dot3(p->t[p->n], p->t[p->n])));
		p->n++;
	}
	p->floor2 = PAIR_FLOOR * PAIR_FLOOR * top * top;
	return 0;
}

/* The error of camera value i as known colour j through M (row-major, t = M c). */
static double pair_error(const pairs *p, const double M[9], int i, int j)
{
	double s = 0;
	for (int r = 0; r < 3; r++) {
		double d = p->t[j][r] - (M[3 * r] * p->c[i][0] + M[3 * r + 1] * p->c[i][1] +
		                         M[3 * r + 2] * p->c[i][2]);
		s += d * d;
	}
	return sqrt(s / (dot3(p->t[j], p->t[j]) + p->floor2));
}

/* M minimising the sum of the pairs' squared errors (those with use[i], all when use
 * is NULL). -1 when the camera values do not span three colours. */
static int fit_matrix(const pairs *p, const int *use, double M[9])
{
	double A[9] = {0}, B[9] = {0}, Ai[9];
	for (int i = 0; i < p->n; i++) {
		if (use && !use[i])
			continue;
		double w = 1 / (dot3(p->t[i], p->t[i]) + p->floor2);
		for (int r = 0; r < 3; r++)
			for (int q = 0; q < 3; q++) {
				A[3 * r + q] += w * p->c[i][r] * p->c[i][q];
				B[3 * r + q] += w * p->t[i][r] * p->c[i][q];
			}
	}
	if (kg_mat3_inverse(A, Ai))
		return -1;
	for (int r = 0; r < 3; r++)
		for (int q = 0; q < 3; q++)
			M[3 * r + q] = B[3 * r] * Ai[q] + B[3 * r + 1] * Ai[3 + q] + B[3 * r + 2] * Ai[6 + q];
	return 0;
}

/* The misfit of a pairing: sqrt(sum e^2 / (n - 3)) under its least-squares matrix (1
 * when there is none: camera values of fewer than three colours). */
static double misfit_of(const pairs *p)
{
	double M[9], s = 0;
	if (p->n <= 3 || fit_matrix(p, NULL, M))
		return 1;
	for (int i = 0; i < p->n; i++) {
		double e = pair_error(p, M, i, i);
		s += e * e;
	}
	return sqrt(s / (p->n - 3));
}

static int cmp_double(const void *pa, const void *pb)
{
	double a = *(const double *)pa, b = *(const double *)pb;
	return a < b ? -1 : a > b;
}

/* The matrix through three pairs exactly; -1 when their camera values are collinear. */
static int matrix_through(const pairs *p, const int q[3], double M[9])
{
	double C[9], Ci[9];
	for (int r = 0; r < 3; r++)
		for (int k = 0; k < 3; k++)
			C[3 * r + k] = p->c[q[k]][r];
	if (kg_mat3_inverse(C, Ci))
		return -1;
	for (int r = 0; r < 3; r++)
		for (int k = 0; k < 3; k++)
			M[3 * r + k] = p->t[q[0]][r] * Ci[k] + p->t[q[1]][r] * Ci[3 + k] +
			               p->t[q[2]][r] * Ci[6 + k];
	return 0;
}

/* The least median error so far (*best, M): the matrix through pairs q, if better. */
static void try_triple(const pairs *p, const int q[3], double *e, double *best, double M[9])
{
	double Mt[9];
	if (q[0] == q[1] || q[1] == q[2] || q[0] == q[2] || matrix_through(p, q, Mt))
		return;
	for (int i = 0; i < p->n; i++)
		e[i] = pair_error(p, Mt, i, i);
	qsort(e, (size_t)p->n, sizeof(double), cmp_double);
	if (e[p->n / 2] < *best) {
		*best = e[p->n / 2];
		memcpy(M, Mt, sizeof(Mt));
	}
}

/* A matrix a few wrong pairs cannot pull: of the matrices through triples of pairs
 * (every triple while there are at most PAIR_MAX_TRIPLES, else that many drawn by a
 * fixed linear congruential sequence), the one with the least median error, refitted
 * by least squares on the pairs within 2.5 times that median (the inliers); *sigma
 * the RMS error of the inliers under it. -1 out of memory or when no triple spans
 * three colours. */
static int robust_matrix(const pairs *p, double M[9], double *sigma)
{
	int n = p->n, q[3];
	double *e = malloc((size_t)n * sizeof(double)), best = INFINITY, Mt[9];
	int *use = calloc((size_t)n, sizeof(int));
	if (e && use && (long)n * (n - 1) * (n - 2) / 6 <= PAIR_MAX_TRIPLES) {
		for (q[0] = 0; q[0] < n; q[0]++)
			for (q[1] = q[0] + 1; q[1] < n; q[1]++)
				for (q[2] = q[1] + 1; q[2] < n; q[2]++)
					try_triple(p, q, e, &best, M);
	} else if (e && use) {
		unsigned seed = 1;
		for (int k = 0; k < PAIR_MAX_TRIPLES; k++) {
			for (int z = 0; z < 3; z++) {
				seed = seed * 1103515245u + 12345u;
				q[z] = (int)((seed >> 8) % (unsigned)n);
			}
			try_triple(p, q, e, &best, M);
		}
	}
	int ret = e && use && isfinite(best) ? 0 : -1, inliers = 0;
	for (int i = 0; ret == 0 && i < n; i++)
		use[i] = pair_error(p, M, i, i) <= 2.5 * best;
	if (ret == 0 && fit_matrix(p, use, Mt) == 0)
		memcpy(M, Mt, sizeof(Mt));
	*sigma = 0;
	for (int i = 0; ret == 0 && i < n; i++)
		if (use[i]) {
			double x = pair_error(p, M, i, i);
			*sigma += x * x;
			inliers++;
		}
	*sigma = inliers ? sqrt(*sigma / inliers) : 0;
	free(e);
	free(use);
	return ret;
}

/* The assignment of rows to columns of the n x n cost a (row-major) with the least
 * sum (the Hungarian method with potentials, O(n^3)): row i to column to[i]. */
static int assign(const double *a, int n, int *to)
{
	double *u = calloc((size_t)n + 1, sizeof(double)), *v = calloc((size_t)n + 1, sizeof(double));
	double *minv = malloc(((size_t)n + 1) * sizeof(double));
	int *col_row = calloc((size_t)n + 1, sizeof(int)), *way = calloc((size_t)n + 1, sizeof(int));
	char *used = malloc((size_t)n + 1);
	int ret = u && v && minv && col_row && way && used ? 0 : -1;
	for (int i = 1; ret == 0 && i <= n; i++) {
		int j0 = 0;
		col_row[0] = i;
		for (int j = 0; j <= n; j++) {
			minv[j] = INFINITY;
			used[j] = 0;
		}
		do {
			used[j0] = 1;
			int i0 = col_row[j0], j1 = 0;
			double delta = INFINITY;
			for (int j = 1; j <= n; j++) {
				if (used[j])
					continue;
				double cur = a[(size_t)(i0 - 1) * n + j - 1] - u[i0] - v[j];
				if (cur < minv[j]) {
					minv[j] = cur;
					way[j] = j0;
				}
				if (minv[j] < delta) {
					delta = minv[j];
					j1 = j;
				}
			}
			for (int j = 0; j <= n; j++) {
				if (used[j]) {
					u[col_row[j]] += delta;
					v[j] -= delta;
				} else {
					minv[j] -= delta;
				}
			}
			j0 = j1;
		} while (col_row[j0] != 0);
		do {
			int j1 = way[j0];
			col_row[j0] = col_row[j1];
			j0 = j1;
		} while (j0);
	}
	for (int j = 1; ret == 0 && j <= n; j++)
		to[col_row[j] - 1] = j - 1;
	free(u);
	free(v);
	free(minv);
	free(col_row);
	free(way);
	free(used);
	return ret;
}

/* The pairs that moved: where the best re-pairing gives camera value i another known
 * colour to[i], i's error as paired stands out from the fit's (above 5 sigma, sigma
 * the robust fit's RMS error of a patch where it belongs, and above
 * KG_CALIB_PAIR_MIN_GAIN) and falls by two thirds or more. A patch that trades places
 * with its twin (a repeated white) or with a similar colour its camera confuses does
 * neither. */
static void moved_pairs(const double *cost, int n, const int *to, double sigma, int *moved)
{
	for (int i = 0; i < n; i++) {
		double own = cost[(size_t)i * n + i], there = cost[(size_t)i * n + to[i]];
		moved[i] = to[i] != i && own > fmax(KG_CALIB_PAIR_MIN_GAIN, 5 * sigma) &&
		           there < own / 3;
	}
}

/* The pairs whose camera values fit other known colours: to[i] (-1: i is where it
 * belongs) for the pairs that moved (moved_pairs); own[i] and moved[i] the errors as
 * paired and re-paired. Returns the number of pairs moved, -1 out of memory. */
static int misplaced(const pairs *p, int *to, double *own, double *moved)
{
	double M[9], sigma;
	int n = p->n, count = 0;
	double *cost = malloc((size_t)n * n * sizeof(double));
	int *flag = malloc((size_t)n * sizeof(int));
	int ret = cost && flag ? 0 : -1;
	if (ret == 0 && robust_matrix(p, M, &sigma) == 0) {
		for (int i = 0; i < n; i++)
			for (int j = 0; j < n; j++)
				cost[(size_t)i * n + j] = pair_error(p, M, i, j);
		ret = assign(cost, n, to);
		if (ret == 0)
			moved_pairs(cost, n, to, sigma, flag);
		for (int i = 0; ret == 0 && i < n; i++) {
			if (!flag[i]) {
				to[i] = -1;
				continue;
			}
			own[i] = cost[(size_t)i * n + i];
			moved[i] = cost[(size_t)i * n + to[i]];
			count++;
		}
	}
	free(cost);
	free(flag);
	return ret ? -1 : count;
}

/* ---- refusals -------------------------------------------------------------------- */

/* "A00 = A01, A01 = A02, A02 = A03, ..." for the first pairs of a map. */
static void map_examples(const calib_pair_side *a, const calib_pair_side *b, const int *map,
                         char *buf, size_t size)
{
	size_t at = 0;
	int shown = 0;
	buf[0] = 0;
	for (int i = 0; i < a->n && shown < 4 && at < size; i++) {
		if (map[i] < 0)
			continue;
		at += (size_t)snprintf(buf + at, size - at, "%s%s = %s", shown ? ", " : "", a->ids[i],
		                       b->ids[map[i]]);
		shown++;
	}
	if (at < size)
		snprintf(buf + at, size - at, ", ...");
}

/* The other pairings in the order they are offered when several give the same pairs:
 * those read from the ids before the files' row order. */
static const kg_id_pairing offered[KG_ID_PAIRING_COUNT] = {
	KG_ID_PAIRING_NAMES, KG_ID_PAIRING_GRID_ORDER, KG_ID_PAIRING_FIRST_BY_NUMBER,
	KG_ID_PAIRING_SECOND_BY_NUMBER, KG_ID_PAIRING_NUMBER_UP, KG_ID_PAIRING_NUMBER_DOWN,
	KG_ID_PAIRING_LETTER_UP, KG_ID_PAIRING_LETTER_DOWN, KG_ID_PAIRING_FILE_ORDER,
};

/* The other pairing that fits best (by file order only when file_order), described
 * in buf: its misfit within the limit and at most half the stated one's. 0 and ""
 * when none does. */
static int suggest(const calib_pair_side *a, const calib_pair_side *b, kg_id_pairing stated,
                   double stated_misfit, int file_order, const char *option, char *buf,
                   size_t size)
{
	int *map = malloc((size_t)a->n * sizeof(int)), *best_map = malloc((size_t)a->n * sizeof(int));
	double best = INFINITY;
	int best_how = -1, best_n = 0;
	buf[0] = 0;
	for (int k = 0; map && best_map && k < KG_ID_PAIRING_COUNT; k++) {
		const char *alias;
		pairs p;
		if (offered[k] == stated || (offered[k] == KG_ID_PAIRING_FILE_ORDER) != file_order ||
		    calib_pair_map(a, b, offered[k], map, &alias) < KG_CALIB_PAIR_MIN_CHECK ||
		    pairs_from(a, b, map, &p))
			continue;
		double m = p.n >= KG_CALIB_PAIR_MIN_CHECK ? misfit_of(&p) : INFINITY;
		if (m < best) {
			best = m;
			best_how = offered[k];
			best_n = p.n;
			memcpy(best_map, map, (size_t)a->n * sizeof(int));
		}
		pairs_free(&p);
	}
	int found = best_how >= 0 && best <= KG_CALIB_PAIR_MAX_MISFIT && best <= stated_misfit / 2;
	if (found) {
		char name[64], ex[200];
		kg_id_pairing_name((kg_id_pairing)best_how, a->role, b->role, name, sizeof(name));
		map_examples(a, b, best_map, ex, sizeof(ex));
		size_t at = (size_t)snprintf(buf, size, "Paired by %s instead (%s), %d patches fit: "
		                             "misfit %.1f %%. ", name, ex, best_n, 100 * best);
		if (at < size && option)
			snprintf(buf + at, size - at, "If the files name the chart so, state it with "
			         "%s %s, or rename the SAMPLE_IDs of one file", option, name);
		else if (at < size)
			snprintf(buf + at, size - at, "Rename the SAMPLE_IDs of one file to match");
	}
	free(map);
	free(best_map);
	return found;
}

/* The pairs the single-patch check moves, in words: "N patches fit other patches'
 * colours far better than their own: ...". Returns how many (0: buf ""), -1 out of
 * memory. */
static int misplaced_text(const calib_pair_side *a, const calib_pair_side *b, const pairs *p,
                          const char *option, char *buf, size_t size)
{
	buf[0] = 0;
	if (p->n > PAIR_MAX_ASSIGN)
		return 0;
	int *to = malloc((size_t)p->n * sizeof(int));
	double *own = malloc((size_t)p->n * sizeof(double)), *moved = malloc((size_t)p->n * sizeof(double));
	int count = to && own && moved ? misplaced(p, to, own, moved) : -1;
	if (2 * count > p->n)
		count = 0; /* not a few patches: the robust fit's premise fails */
	char ids[240] = "";
	size_t at = 0, ai = 0;
	if (count > 0)
		at = (size_t)snprintf(buf, size, "%d patch%s fit%s other patches' colours far better "
		                      "than their own (mislabelled or swapped?); %s's patch -> the "
		                      "patch of %s it fits (error; as paired): ", count,
		                      count == 1 ? "" : "es", count == 1 ? "s" : "", b->file, a->file);
	for (int i = 0, shown = 0; count > 0 && i < p->n; i++) {
		if (to[i] < 0)
			continue;
		const char *bid = b->ids[p->ib[i]];
		if (shown < 4 && at < size)
			at += (size_t)snprintf(buf + at, size - at, "%s%s -> %s (%.0f %%; %.0f %%)",
			                       shown ? ", " : "", bid, a->ids[p->ia[to[i]]], 100 * moved[i],
			                       100 * own[i]);
		else if (shown == 4 && at < size)
			at += (size_t)snprintf(buf + at, size - at, " and %d more", count - 4);
		if (ai < sizeof(ids))
			ai += (size_t)snprintf(ids + ai, sizeof(ids) - ai, "%s%s", shown ? "," : "", bid);
		shown++;
	}
	if (count > 0 && at < size)
		snprintf(buf + at, size - at, ". Correct the SAMPLE_IDs, or leave the patches out%s%s",
		         option ? " with --exclude " : "", option ? ids : "");
	free(to);
	free(own);
	free(moved);
	return count;
}

/* Why the stated pairing failed, and what would fit: an id convention (a pairing read
 * from the ids), else (only when `any`) a few patches that moved, the files' row order
 * or nothing. 1 when buf holds an explanation, 0 when none was found, -1 out of
 * memory. */
static int explain(const calib_pair_side *a, const calib_pair_side *b, kg_id_pairing how,
                   const pairs *p, double misfit, int any, const char *option, char *buf,
                   size_t size)
{
	if (suggest(a, b, how, misfit, 0, option, buf, size))
		return 1;
	if (!any)
		return 0;
	int moved = misplaced_text(a, b, p, option, buf, size);
	if (moved != 0)
		return moved < 0 ? -1 : 1;
	if (!suggest(a, b, how, misfit, 1, option, buf, size))
		snprintf(buf, size, "No other pairing fits (grid order, either file's ids by number, "
		         "ids one number or letter apart, file order): are both files of the same "
		         "chart, and the camera values linear (not gamma-encoded)?");
	return 1;
}

/* A pairing whose misfit is above the limit: refused with the explanation; when
 * not `any`, only if another pairing read from the ids fits. */
static int refuse_misfit(const calib_pair_side *a, const calib_pair_side *b,
                         kg_id_pairing how, const pairs *p, double misfit, int any,
                         const char *option, kg_err *err)
{
	char da[240], db[200], why[700], name[64];
	int found = explain(a, b, how, p, misfit, any, option, why, sizeof(why));
	if (found <= 0)
		return found ? kg_fail(err, KG_ENOMEM, "out of memory") : 0;
	describe_ids(a, b, da, sizeof(da));
	describe_ids(b, NULL, db, sizeof(db));
	kg_id_pairing_name(how, a->role, b->role, name, sizeof(name));
	if (strcmp(da, db) == 0)
		snprintf(db, sizeof(db), "the same");
	return kg_fail(err, KG_EINVAL,
	               "%s and %s: the %d patches paired by %s are not the same patches: %s miss "
	               "the camera values by %.1f %% through the best 3 x 3 matrix (correct "
	               "pairings: under %.0f %%). Ids: %s in %s, %s in %s. %s",
	               a->file, b->file, p->n, how == KG_ID_PAIRING_NAMES ? "SAMPLE_ID" : name,
	               a->what, 100 * misfit, 100 * KG_CALIB_PAIR_MAX_MISFIT, da, a->file, db,
	               b->file, why);
}

/* Pairs that fit as a whole may still hold a few patches that fit others' colours. */
static int check_patches(const calib_pair_side *a, const calib_pair_side *b, const pairs *p,
                         const char *option, kg_err *err)
{
	char why[900];
	int moved = misplaced_text(a, b, p, option, why, sizeof(why));
	if (moved < 0)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	if (moved == 0)
		return 0;
	return kg_fail(err, KG_EINVAL, "%s and %s: of the %d patches paired by SAMPLE_ID, %s",
	               a->file, b->file, p->n, why);
}

/* ---- the check ------------------------------------------------------------------ */

void calib_pair_result_free(calib_pair_result *r)
{
	free(r->match);
	memset(r, 0, sizeof(*r));
	r->misfit = NAN;
}

/* Camera values that do not span three colours (greys, two inks) cannot tell a 3 x 3
 * matrix: they are left to the collinearity refusal. */
static int spans_three(const pairs *p)
{
	double cond, cond_eq, sv[3], sv_eq[3];
	kg_err ignored = {{0}};
	return calib_rgb_conditioning((const double(*)[3])p->c, p->n, &cond, &cond_eq, sv, sv_eq,
	                              &ignored) == 0 &&
	       cond_eq <= KG_CALIB_MAX_COND;
}

int calib_pair_check(const calib_pair_side *a, const calib_pair_side *b, kg_id_pairing how,
                     int whole, const char *option, calib_pair_result *r, kg_err *err)
{
	memset(r, 0, sizeof(*r));
	r->misfit = NAN;
	r->match = malloc((a->n > 0 ? (size_t)a->n : 1) * sizeof(int));
	if (!r->match || (r->npairs = calib_pair_map(a, b, how, r->match, &r->alias)) < 0) {
		calib_pair_result_free(r);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	pairs p;
	if (pairs_from(a, b, r->match, &p)) {
		calib_pair_result_free(r);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	r->nchecked = p.n;
	int ret = 0;
	if (p.n >= KG_CALIB_PAIR_MIN_CHECK && spans_three(&p)) {
		r->misfit = misfit_of(&p);
		if (r->misfit > KG_CALIB_PAIR_MAX_MISFIT)
			ret = refuse_misfit(a, b, how, &p, r->misfit, whole, option, err);
		else if (whole)
			ret = check_patches(a, b, &p, option, err);
	}
	pairs_free(&p);
	if (ret)
		calib_pair_result_free(r);
	return ret;
}

int calib_pair_check_patches(const calib_pair_side *a, const calib_pair_side *b,
                             const calib_pair_result *r, const char *option, kg_err *err)
{
	pairs p;
	if (pairs_from(a, b, r->match, &p))
		return kg_fail(err, KG_ENOMEM, "out of memory");
	int ret = p.n >= KG_CALIB_PAIR_MIN_CHECK && spans_three(&p)
	              ? check_patches(a, b, &p, option, err) : 0;
	pairs_free(&p);
	return ret;
}

int calib_pair_moved(const calib_pair_side *a, const calib_pair_side *b,
                     const calib_pair_result *r, const char *option, char *buf, size_t size)
{
	pairs p;
	buf[0] = 0;
	if (pairs_from(a, b, r->match, &p))
		return -1;
	int count = p.n >= KG_CALIB_PAIR_MIN_CHECK && spans_three(&p)
	                ? misplaced_text(a, b, &p, option, buf, size) : 0;
	pairs_free(&p);
	return count;
}

/* The ids of a side that no pair uses. */
static int unpaired_ids(const calib_pair_side *s, const int *used, char ***out, int *n)
{
	*n = 0;
	*out = calloc(s->n > 0 ? (size_t)s->n : 1, sizeof(char *));
	if (!*out)
		return -1;
	for (int i = 0; i < s->n; i++)
		if (!used[i] && !((*out)[(*n)++] = strdup(s->ids[i])))
			return -1;
	return 0;
}

int calib_pair_record(const calib_pair_side *a, const calib_pair_side *b,
                      const calib_pair_result *r, kg_id_pairing how, kg_pairing_record *rec,
                      kg_err *err)
{
	kg_pairing_record_free(rec);
	rec->rule = how;
	rec->pairs = r->npairs;
	rec->checked = r->nchecked;
	rec->misfit = r->misfit;
	int *used_a = calloc((size_t)a->n + 1, sizeof(int)), *used_b = calloc((size_t)b->n + 1, sizeof(int));
	int ret = used_a && used_b ? 0 : -1;
	for (int i = 0; ret == 0 && i < a->n; i++)
		if (r->match[i] >= 0)
			used_a[i] = used_b[r->match[i]] = 1;
	if (ret == 0)
		ret = unpaired_ids(a, used_a, &rec->unpaired[0], &rec->nunpaired[0]);
	if (ret == 0)
		ret = unpaired_ids(b, used_b, &rec->unpaired[1], &rec->nunpaired[1]);
	free(used_a);
	free(used_b);
	if (ret) {
		kg_pairing_record_free(rec);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	return 0;
}
