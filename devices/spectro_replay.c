/* replay: a spectrometer that plays back a recording, and the recorder that writes one.
 *
 * URI replay:<recording>. A recording (kogei-spectro-recording/1) is a text file:
 *
 *   # comment lines and blank lines are ignored
 *   format kogei-spectro-recording/1
 *   backend usbspec                       the recorded instrument's URI scheme
 *   model USB4000                         rest of the line
 *   serial USB4C05678                     rest of the line
 *   pixels 3840
 *   wavelength c0 c1 c2 c3
 *   dark_pixels first last                (-1 -1 when none)
 *   nonlinearity_order n                  (-1 when none)
 *   nonlinearity k0 ... kn                (n + 1 values; empty when n is -1)
 *   saturation 65535
 *   integration_range min_us max_us
 *   high_speed 0|1
 *   read 1 100000 dark                    read number, integration time (us), target
 *   <pixels raw counts, 16 a line>
 *   read 2 ...
 *   end 2                                 number of reads
 *
 * Every number is written with %.17g, so the doubles read back bit for bit. The target
 * is the rest of the read line: what kg_spectro_set_target last named ("dark",
 * "white", a sample id), empty when nothing was named.
 *
 * Replay serves the recorded reads in order. Each read must be asked for at the
 * recorded integration time and target; otherwise the read fails (KG_EINVAL) naming
 * the read number and what the recording expected. A read past the last recorded one
 * fails like a device that stopped answering (KG_ENODEV). */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "spectro_driver.h"

#define REC_FORMAT "kogei-spectro-recording/1"
#define REC_PER_LINE 16

/* ---- recorder ---- */

struct kg_spectro_recorder {
	kg_outfile out;
	int npixels;
	int nreads;
	char *target; /* last target named, NULL for none */
	int bad;      /* a target that cannot be written */
	char bad_target[64];
};

int kg_recorder_open(const char *path, const kg_spectro_info *info, kg_spectro_recorder **out,
                     kg_err *err)
{
	kg_spectro_recorder *r = calloc(1, sizeof(*r));
	if (!r)
		return KG_ENOMEM;
	int rc = kg_outfile_open(&r->out, path, 0, err);
	if (rc) {
		free(r);
		return rc;
	}
	r->npixels = info->npixels;
	FILE *f = r->out.fp;
	fprintf(f, "# kogei spectrometer recording: play back with --spectro replay:<this file>\n");
	fprintf(f, "format %s\n", REC_FORMAT);
	fprintf(f, "backend %s\nmodel %s\nserial %s\npixels %d\n", info->backend, info->model,
	        info->serial, info->npixels);
	fprintf(f, "wavelength %.17g %.17g %.17g %.17g\n", info->wl_coeffs[0], info->wl_coeffs[1],
	        info->wl_coeffs[2], info->wl_coeffs[3]);
	fprintf(f, "dark_pixels %d %d\n", info->dark_first, info->dark_last);
	fprintf(f, "nonlinearity_order %d\nnonlinearity", info->nl_order);
	for (int k = 0; k <= info->nl_order && k < KG_SPECTRO_MAX_NL; k++)
		fprintf(f, " %.17g", info->nl_coeffs[k]);
	fprintf(f, "\nsaturation %.17g\nintegration_range %u %u\nhigh_speed %d\n",
	        info->saturation, info->min_integration_us, info->max_integration_us,
	        info->high_speed);
	*out = r;
	return 0;
}

void kg_recorder_target(kg_spectro_recorder *r, const char *what)
{
	free(r->target);
	r->target = what ? strdup(what) : NULL;
	if (what && !r->target)
		r->bad = KG_ENOMEM;
	for (const char *c = what; c && *c && !r->bad; c++)
		if ((unsigned char)*c < 0x20) {
			r->bad = KG_EINVAL;
			snprintf(r->bad_target, sizeof(r->bad_target), "%s", what);
		}
}

void kg_recorder_read(kg_spectro_recorder *r, uint32_t us, const double *counts)
{
	FILE *f = r->out.fp;
	fprintf(f, "read %d %u%s%s\n", ++r->nreads, us, r->target ? " " : "",
	        r->target ? r->target : "");
	for (int p = 0; p < r->npixels; p++)
		fprintf(f, "%.17g%c", counts[p],
		        (p + 1) % REC_PER_LINE == 0 || p + 1 == r->npixels ? '\n' : ' ');
}

int kg_recorder_close(kg_spectro_recorder **rp, int *nreads, kg_err *err)
{
	kg_spectro_recorder *r = *rp;
	if (nreads)
		*nreads = r ? r->nreads : 0;
	if (!r)
		return 0;
	*rp = NULL;
	int rc = 0;
	if (r->bad == KG_EINVAL) {
		rc = kg_fail(err, KG_EINVAL,
		             "%s: recording: target '%s' contains a control character and cannot "
		             "be recorded", r->out.path, r->bad_target);
		kg_outfile_abort(&r->out);
	} else if (r->bad) {
		rc = r->bad;
		kg_outfile_abort(&r->out);
	} else {
		fprintf(r->out.fp, "end %d\n", r->nreads);
		rc = kg_outfile_commit(&r->out, err);
	}
	free(r->target);
	free(r);
	return rc;
}

/* ---- replay ---- */

typedef struct replay_state {
	char *path;
	char backend[16];
	kg_spectro_info info;
	int nreads, next;
	uint32_t *us;
	char **targets;  /* NULL for none */
	double *counts;  /* nreads x npixels */
	uint32_t integration_us;
	char *target;    /* what the caller named last, NULL for none */
} replay_state;

static void replay_close(void *state)
{
	replay_state *s = state;
	for (int i = 0; i < s->nreads; i++)
		free(s->targets[i]);
	free(s->targets);
	free(s->us);
	free(s->counts);
	free(s->target);
	free(s->path);
	free(s);
}

/* Parse exactly n numbers from text (all of it). Returns the count found, or -1 for
 * something that is not a number. */
static int parse_numbers(const char *text, double *v, int n)
{
	int k = 0;
	const char *p = text;
	for (;;) {
		while (*p == ' ' || *p == '\t')
			p++;
		if (!*p)
			return k;
		char *end;
		errno = 0;
		double x = strtod(p, &end);
		if (end == p || (*end && *end != ' ' && *end != '\t'))
			return -1;
		if (k < n)
			v[k] = x;
		k++;
		p = end;
	}
}

static int grow(replay_state *s, int *cap)
{
	if (s->nreads < *cap)
		return 0;
	int nc = *cap ? *cap * 2 : 16;
	uint32_t *us = realloc(s->us, sizeof(*us) * nc);
	if (!us)
		return KG_ENOMEM;
	s->us = us;
	char **t = realloc(s->targets, sizeof(*t) * nc);
	if (!t)
		return KG_ENOMEM;
	s->targets = t;
	double *c = realloc(s->counts, sizeof(double) * (size_t)nc * s->info.npixels);
	if (!c)
		return KG_ENOMEM;
	s->counts = c;
	*cap = nc;
	return 0;
}

/* Header keys, in the order they are required (all before the first read). */
enum { H_FORMAT, H_BACKEND, H_MODEL, H_SERIAL, H_PIXELS, H_WL, H_DARK, H_NLORDER, H_NL,
       H_SAT, H_RANGE, H_HS, H_COUNT };
static const char *const hkeys[H_COUNT] = {
	"format", "backend", "model", "serial", "pixels", "wavelength", "dark_pixels",
	"nonlinearity_order", "nonlinearity", "saturation", "integration_range", "high_speed"};

static int replay_parse(replay_state *s, char *buf, kg_err *err)
{
	const char *path = s->path;
	kg_spectro_info *info = &s->info;
	int have[H_COUNT] = {0};
	int cap = 0, lineno = 0, got = 0; /* counts of the current read so far */
	int ended = 0, r = 0;
	double v[KG_SPECTRO_MAX_NL + 1] = {0};
	char *line = buf;
	while (line && !r) {
		char *nl = strchr(line, '\n');
		if (nl)
			*nl = '\0';
		size_t len = strlen(line);
		if (len && line[len - 1] == '\r')
			line[--len] = '\0';
		lineno++;
		char *cur = line;
		line = nl ? nl + 1 : NULL;
		if (!*cur || *cur == '#')
			continue;
		/* Counts of the read in progress. */
		if (s->nreads && got < info->npixels) {
			double *dst = s->counts + (size_t)(s->nreads - 1) * info->npixels + got;
			int k = parse_numbers(cur, dst, info->npixels - got);
			if (k < 0 || got + k > info->npixels)
				return kg_fail(err, KG_EINVAL,
				               "%s: line %d: read %d: expected %d raw counts, found %s",
				               path, lineno, s->nreads, info->npixels,
				               k < 0 ? "something that is not a number" : "more");
			got += k;
			continue;
		}
		if (ended)
			return kg_fail(err, KG_EINVAL, "%s: line %d: text after the end line", path,
			               lineno);
		char *sp = strchr(cur, ' ');
		char *val = sp ? sp + 1 : cur + strlen(cur);
		size_t klen = sp ? (size_t)(sp - cur) : strlen(cur);
		if (klen == 4 && !strncmp(cur, "read", 4)) {
			for (int h = 0; h < H_COUNT; h++)
				if (!have[h])
					return kg_fail(err, KG_EINVAL,
					               "%s: line %d: read before the '%s' line of the header",
					               path, lineno, hkeys[h]);
			char *end;
			long n = strtol(val, &end, 10);
			unsigned long us = *end == ' ' ? strtoul(end + 1, &end, 10) : 0;
			if (n != s->nreads + 1 || us == 0 || us > UINT32_MAX || (*end && *end != ' '))
				return kg_fail(err, KG_EINVAL,
				               "%s: line %d: expected 'read %d <integration us> [target]'",
				               path, lineno, s->nreads + 1);
			if ((r = grow(s, &cap)) != 0)
				break;
			s->us[s->nreads] = (uint32_t)us;
			s->targets[s->nreads] = NULL;
			if (*end == ' ' && !(s->targets[s->nreads] = strdup(end + 1)))
				r = KG_ENOMEM;
			s->nreads++;
			got = 0;
			continue;
		}
		if (klen == 3 && !strncmp(cur, "end", 3)) {
			char *end;
			long n = strtol(val, &end, 10);
			if (*end || end == val || n != s->nreads)
				return kg_fail(err, KG_EINVAL,
				               "%s: line %d: the end line says %s reads, the file has %d",
				               path, lineno, val, s->nreads);
			ended = 1;
			continue;
		}
		int h = 0;
		while (h < H_COUNT && !(strlen(hkeys[h]) == klen && !strncmp(hkeys[h], cur, klen)))
			h++;
		if (h == H_COUNT || s->nreads)
			return kg_fail(err, KG_EINVAL, "%s: line %d: unexpected '%.*s'", path, lineno,
			               (int)klen, cur);
		if (h != H_FORMAT && !have[H_FORMAT])
			return kg_fail(err, KG_EINVAL, "%s: line %d: expected 'format %s' first", path,
			               lineno, REC_FORMAT);
		have[h] = 1;
		int want = 0, k = 0;
		switch (h) {
		case H_FORMAT:
			if (strcmp(val, REC_FORMAT))
				return kg_fail(err, KG_EINVAL, "%s: line %d: format '%s': expected %s",
				               path, lineno, val, REC_FORMAT);
			break;
		case H_BACKEND: snprintf(s->backend, sizeof(s->backend), "%s", val); break;
		case H_MODEL: snprintf(info->model, sizeof(info->model), "%s", val); break;
		case H_SERIAL: snprintf(info->serial, sizeof(info->serial), "%s", val); break;
		case H_PIXELS:
			want = 1;
			k = parse_numbers(val, v, 1);
			if (k == 1 && !(v[0] >= 2 && v[0] <= 1e6 && v[0] == (int)v[0]))
				k = -1;
			info->npixels = (int)v[0];
			break;
		case H_WL:
			want = 4;
			if ((k = parse_numbers(val, v, 4)) == 4)
				memcpy(info->wl_coeffs, v, sizeof(info->wl_coeffs));
			break;
		case H_DARK:
			want = 2;
			k = parse_numbers(val, v, 2);
			info->dark_first = (int)v[0];
			info->dark_last = (int)v[1];
			break;
		case H_NLORDER:
			want = 1;
			k = parse_numbers(val, v, 1);
			if (k == 1 && !(v[0] >= -1 && v[0] < KG_SPECTRO_MAX_NL))
				k = -1;
			info->nl_order = (int)v[0];
			break;
		case H_NL:
			if (!have[H_NLORDER])
				return kg_fail(err, KG_EINVAL,
				               "%s: line %d: nonlinearity before nonlinearity_order", path,
				               lineno);
			want = info->nl_order + 1;
			if ((k = parse_numbers(val, v, KG_SPECTRO_MAX_NL)) == want)
				memcpy(info->nl_coeffs, v, sizeof(double) * want);
			break;
		case H_SAT:
			want = 1;
			k = parse_numbers(val, v, 1);
			info->saturation = v[0];
			break;
		case H_RANGE:
			want = 2;
			k = parse_numbers(val, v, 2);
			if (k == 2 && !(v[0] >= 1 && v[0] <= v[1] && v[1] <= UINT32_MAX))
				k = -1;
			info->min_integration_us = (uint32_t)v[0];
			info->max_integration_us = (uint32_t)v[1];
			break;
		case H_HS:
			want = 1;
			k = parse_numbers(val, v, 1);
			info->high_speed = v[0] != 0;
			break;
		}
		if (k != want)
			return kg_fail(err, KG_EINVAL, "%s: line %d: %s: expected %d valid number%s",
			               path, lineno, hkeys[h], want, want == 1 ? "" : "s");
	}
	if (r)
		return r;
	for (int h = 0; h < H_COUNT; h++)
		if (!have[h])
			return kg_fail(err, KG_EINVAL,
			               "%s: no '%s' line: not a complete %s file", path, hkeys[h],
			               REC_FORMAT);
	if (s->nreads && got < info->npixels)
		return kg_fail(err, KG_EINVAL,
		               "%s: read %d has %d of %d raw counts: the recording is cut short",
		               path, s->nreads, got, info->npixels);
	if (!ended)
		return kg_fail(err, KG_EINVAL,
		               "%s: no 'end' line after %d reads: the recording is cut short or not "
		               "a %s file", path, s->nreads, REC_FORMAT);
	return 0;
}

static int replay_open(const char *target, void **state, kg_err *err)
{
	if (!*target)
		return kg_fail(err, KG_EINVAL, "replay: expected replay:<recording file>");
	replay_state *s = calloc(1, sizeof(*s));
	if (!s)
		return KG_ENOMEM;
	s->info.dark_first = s->info.dark_last = -1;
	s->info.nl_order = -1;
	char *buf = NULL;
	int r = (s->path = strdup(target)) ? kg_read_file(target, &buf, NULL, err) : KG_ENOMEM;
	if (!r)
		r = replay_parse(s, buf, err);
	free(buf);
	if (r) {
		replay_close(s);
		return r;
	}
	*state = s;
	return 0;
}

static int replay_identify(void *state, kg_spectro_info *info, kg_err *err)
{
	replay_state *s = state;
	snprintf(info->model, sizeof(info->model), "%s", s->info.model);
	snprintf(info->serial, sizeof(info->serial), "%s", s->info.serial);
	info->npixels = s->info.npixels;
	info->saturation = s->info.saturation;
	info->min_integration_us = s->info.min_integration_us;
	info->max_integration_us = s->info.max_integration_us;
	info->high_speed = s->info.high_speed;
	return 0;
}

static int replay_wavelengths(void *state, double coeffs[4], kg_err *err)
{
	memcpy(coeffs, ((replay_state *)state)->info.wl_coeffs, sizeof(double) * 4);
	return 0;
}

static void replay_dark_pixels(void *state, int *first, int *last)
{
	*first = ((replay_state *)state)->info.dark_first;
	*last = ((replay_state *)state)->info.dark_last;
}

static int replay_nonlinearity(void *state, double coeffs[KG_SPECTRO_MAX_NL], int *order,
                               kg_err *err)
{
	replay_state *s = state;
	*order = s->info.nl_order;
	memcpy(coeffs, s->info.nl_coeffs, sizeof(double) * KG_SPECTRO_MAX_NL);
	return 0;
}

static int replay_set_integration(void *state, uint32_t us, kg_err *err)
{
	((replay_state *)state)->integration_us = us;
	return 0;
}

static int replay_set_target(void *state, const char *what, kg_err *err)
{
	replay_state *s = state;
	free(s->target);
	s->target = what ? strdup(what) : NULL;
	return what && !s->target ? KG_ENOMEM : 0;
}

static void describe(char *buf, size_t n, const char *target, uint32_t us)
{
	if (target)
		snprintf(buf, n, "target '%.200s' at %u us", target, us);
	else
		snprintf(buf, n, "no target at %u us", us);
}

static int replay_read_raw(void *state, double *counts, kg_err *err)
{
	replay_state *s = state;
	char asked[256], want[256];
	describe(asked, sizeof(asked), s->target, s->integration_us);
	int i = s->next;
	if (i >= s->nreads)
		return kg_fail(err, KG_ENODEV,
		               "replay:%s: read %d (%s) asked for, but the recording ends after %d "
		               "read%s: the recorded run stopped here", s->path, i + 1, asked,
		               s->nreads, s->nreads == 1 ? "" : "s");
	const char *t = s->targets[i];
	int same_target = (!t && !s->target) || (t && s->target && !strcmp(t, s->target));
	if (!same_target || s->us[i] != s->integration_us) {
		describe(want, sizeof(want), t, s->us[i]);
		return kg_fail(err, KG_EINVAL,
		               "replay:%s: read %d: the recording expects %s, the measurement asked "
		               "for %s (replay the same run: integration time, averaging, patches "
		               "and answers)", s->path, i + 1, want, asked);
	}
	memcpy(counts, s->counts + (size_t)i * s->info.npixels, sizeof(double) * s->info.npixels);
	s->next++;
	return 0;
}

const kg_spectro_driver kg_spectro_replay_driver = {
	.scheme = "replay",
	.description = "plays back a recording made with kogei measure --record",
	.open = replay_open,
	.identify = replay_identify,
	.wavelength_calibration = replay_wavelengths,
	.dark_pixels = replay_dark_pixels,
	.nonlinearity = replay_nonlinearity,
	.set_integration = replay_set_integration,
	.read_raw = replay_read_raw,
	.set_target = replay_set_target,
	.close = replay_close,
};
