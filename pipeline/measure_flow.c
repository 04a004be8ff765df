/* The guided spectrometer measurement (kg_pipeline.h). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "kg_pipeline.h"

static void say(const kg_measure_flow *m, const char *fmt, ...) KG_PRINTF(2, 3);
static void say(const kg_measure_flow *m, const char *fmt, ...)
{
	char line[1024];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(line, sizeof(line), fmt, ap);
	va_end(ap);
	if (m->ui.say)
		m->ui.say(m->ui.user, line);
}

/* The session's warnings (saturation, pixels without white signal). */
static void warn_ui(void *user, const char *message)
{
	say(user, "warning: %s", message);
}

void kg_measure_flow_init(kg_measure_flow *m)
{
	m->s.warn = warn_ui;
	m->s.warn_user = m;
}

int kg_measure_flow_ask(kg_measure_flow *m, const char *allowed, const char *fmt, ...)
{
	char prompt[512];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(prompt, sizeof(prompt), fmt, ap);
	va_end(ap);
	if (m->yes || !m->ui.ask) {
		say(m, "%s", prompt);
		return 'm';
	}
	return m->ui.ask(m->ui.user, allowed, prompt);
}

int kg_measure_flow_dark(kg_measure_flow *m, kg_err *err)
{
	if (kg_measure_flow_ask(m, "", "Cover the probe (dark reference).") == 'q')
		return 1;
	kg_spectro_reading_clear(&m->s.dark);
	return kg_measure_reading(&m->s, "dark", "dark reference", &m->s.dark, err);
}

/* Measure the white; with a previous white, report how far it drifted. */
int kg_measure_flow_white(kg_measure_flow *m, kg_err *err)
{
	if (kg_measure_flow_ask(m, "", "Put the probe on the white standard (white reference).") ==
	    'q')
		return 1;
	kg_spectro_reading w = {0};
	int r = kg_measure_reading(&m->s, "white", "white reference", &w, err);
	if (r)
		return r;
	if (m->s.white.n) {
		double d = kg_white_drift(&m->s.dark, &m->s.white, &w);
		say(m, "white reference changed by %+.2f %% since the last one", 100 * d);
		if (fabs(d) > KG_WHITE_DRIFT_LIMIT)
			say(m, "warning: the white reference drifted by %+.1f %% (more than %.0f %%): "
			       "lamp or probe changed; readings since the last white may be off",
			    100 * d, 100 * KG_WHITE_DRIFT_LIMIT);
	}
	kg_spectro_reading_clear(&m->s.white);
	m->s.white = w;
	m->white_age_warned = 0;
	return 0;
}

int kg_measure_flow_sample(kg_measure_flow *m, const char *id, kg_spectrum *out, kg_err *err)
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	double age = (double)ts.tv_sec - m->s.white.when;
	if (age > m->white_max_age && !m->white_age_warned) {
		say(m, "warning: the white reference is %.0f s old (limit %.0f s): answer w to "
		       "measure it again", age, m->white_max_age);
		m->white_age_warned = 1;
	}
	return kg_measure_sample(&m->s, id, out, err);
}

/* Output keywords: instrument, serial, settings. */
int kg_measure_flow_write(const kg_measure_flow *m, const char *path, kg_patchset *ps,
                          kg_err *err)
{
	return kg_measure_write(&m->s, path, ps, "kogei measure", NULL, err);
}

void kg_patch_list_free(kg_patch_list *l)
{
	for (int i = 0; i < l->n; i++) {
		free(l->ids[i]);
		free(l->places[i]);
	}
	free(l->ids);
	free(l->places);
	memset(l, 0, sizeof(*l));
}

static int patch_list_add(kg_patch_list *l, const char *id, const char *place)
{
	char **ids = realloc(l->ids, sizeof(char *) * (l->n + 1));
	if (!ids)
		return KG_ENOMEM;
	l->ids = ids;
	char **places = realloc(l->places, sizeof(char *) * (l->n + 1));
	if (!places)
		return KG_ENOMEM;
	l->places = places;
	l->ids[l->n] = strdup(id);
	l->places[l->n] = strdup(place);
	l->n++;
	return l->ids[l->n - 1] && l->places[l->n - 1] ? 0 : KG_ENOMEM;
}

int kg_patch_list_load(const char *chart, const char *list, const char *file,
                       kg_patch_list *l, kg_err *err)
{
	int r = 0;
	if (chart) {
		kg_chart_layout *lay = NULL;
		if ((r = kg_chart_layout_load(chart, &lay, err)) != 0)
			return r;
		const char *unit = lay->template_units ? "units" : "mm";
		for (int i = 0; !r && i < lay->npatches; i++) {
			const kg_chart_patch *p = &lay->patches[i];
			char place[160];
			snprintf(place, sizeof(place), "%s%s%s at x %.0f %s, y %.0f %s from the top left of %s",
			         p->name[0] ? "\"" : "", p->name, p->name[0] ? "\" " : "",
			         p->center_mm[0], unit, p->center_mm[1], unit, lay->name);
			r = patch_list_add(l, p->id, place);
		}
		kg_chart_layout_free(&lay);
	} else if (list) {
		char *copy = strdup(list), *save = NULL;
		if (!copy)
			return KG_ENOMEM;
		for (char *t = strtok_r(copy, ",", &save); !r && t; t = strtok_r(NULL, ",", &save))
			r = patch_list_add(l, t, "");
		free(copy);
	} else if (file) {
		kg_patchset *ps = NULL;
		if ((r = kg_patchset_read(file, KG_RESAMPLE_EXTRAPOLATE, &ps, err)) != 0)
			return r;
		for (int i = 0; !r && i < ps->n; i++)
			r = patch_list_add(l, ps->ids[i], "");
		kg_patchset_free(&ps);
	}
	for (int i = 0; !r && i < l->n; i++)
		for (int j = 0; j < i; j++)
			if (!strcmp(l->ids[i], l->ids[j]))
				r = kg_fail(err, KG_EINVAL, "patch id '%s' appears twice", l->ids[i]);
	if (!r && l->n == 0)
		r = kg_fail(err, KG_EINVAL, "no patches to measure");
	return r;
}

int kg_measure_flow_chart(kg_measure_flow *m, const kg_patch_list *pl, const char *out,
                          int resume, int check_white, kg_err *err)
{
	char *partial = malloc(strlen(out) + 9);
	if (!partial)
		return KG_ENOMEM;
	sprintf(partial, "%s.partial", out);
	kg_patchset *ps = NULL, *done = NULL;
	unsigned char *have = calloc(pl->n, 1);
	int r = have ? kg_patchset_new(pl->n, KG_PATCH_SPECTRA, &ps, err) : KG_ENOMEM;
	for (int i = 0; !r && i < pl->n; i++)
		r = kg_patchset_set_id(ps, i, pl->ids[i], err);
	struct stat st;
	int exists = stat(partial, &st) == 0;
	if (!r && exists && !resume)
		r = kg_fail(err, KG_EINVAL,
		            "%s: an interrupted measurement is there: add --resume to continue it or "
		            "remove the file", partial);
	if (!r && resume && exists) {
		r = kg_patchset_read(partial, 0, &done, err);
		kg_inputs_forget(partial); /* this run's own progress, rewritten after each patch */
		for (int i = 0; !r && i < done->n; i++) {
			int k = kg_patchset_find(ps, done->ids[i]);
			if (k < 0 || !done->spectra) {
				r = kg_fail(err, KG_EINVAL, "%s: patch '%s' is not one of this chart's",
				            partial, done->ids[i]);
				break;
			}
			ps->spectra[k] = done->spectra[i];
			have[k] = 1;
		}
		if (!r)
			say(m, "resuming: %d of %d patches already measured in %s",
			    done->n, pl->n, partial);
	}
	int rc = r;
	if (!rc)
		rc = kg_measure_flow_dark(m, err);
	if (!rc)
		rc = kg_measure_flow_white(m, err);
	int last = -1, ndone = 0;
	for (int i = 0; i < pl->n; i++)
		ndone += have[i];
	int i = 0;
	while (!rc && i < pl->n) {
		if (have[i]) {
			i++;
			continue;
		}
		int c = kg_measure_flow_ask(m, last >= 0 ? "rw" : "w", "[%d/%d] Put the probe on patch %s%s%s.",
		            ndone + 1, pl->n, pl->ids[i], pl->places[i][0] ? " " : "",
		            pl->places[i]);
		int target = i;
		if (c == 'q') {
			rc = 1;
			break;
		}
		if (c == 'w') {
			rc = kg_measure_flow_white(m, err);
			continue;
		}
		if (c == 'r') {
			target = last;
			say(m, "Put the probe on patch %s again.", pl->ids[target]);
		}
		kg_spectrum s;
		if ((rc = kg_measure_flow_sample(m, pl->ids[target], &s, err)) != 0)
			break;
		ps->spectra[target] = s;
		if (!have[target])
			ndone++;
		have[target] = 1;
		last = target;
		say(m, "measured %s (%d of %d)", pl->ids[target], ndone, pl->n);
		/* Save what is measured so far: an interruption loses nothing. */
		kg_patchset *sofar = NULL;
		int k = 0;
		if ((rc = kg_patchset_new(ndone, KG_PATCH_SPECTRA, &sofar, err)) != 0)
			break;
		for (int j = 0; !rc && j < pl->n; j++) {
			if (!have[j])
				continue;
			sofar->spectra[k] = ps->spectra[j];
			rc = kg_patchset_set_id(sofar, k++, pl->ids[j], err);
		}
		if (!rc)
			rc = kg_measure_flow_write(m, partial, sofar, err);
		kg_patchset_free(&sofar);
	}
	if (!rc && check_white) {
		kg_spectro_reading before = m->s.white;
		m->s.white = (kg_spectro_reading){0};
		rc = kg_measure_flow_white(m, err);
		if (!rc) {
			double d = kg_white_drift(&m->s.dark, &before, &m->s.white);
			say(m, "white reference drift over the chart: %+.2f %%", 100 * d);
		}
		if (!rc && fabs(kg_white_drift(&m->s.dark, &before, &m->s.white)) > KG_WHITE_DRIFT_LIMIT)
			say(m, "warning: the white reference drifted by more than %.0f %% "
			       "during the chart: consider measuring it again",
			    100 * KG_WHITE_DRIFT_LIMIT);
		kg_spectro_reading_clear(&before);
	}
	if (!rc) {
		rc = kg_measure_flow_write(m, out, ps, err);
		if (!rc)
			unlink(partial);
	} else if (ndone > 0) {
		say(m, "kogei: %d of %d patches are saved in %s; run again with --resume "
		       "to continue", ndone, pl->n, partial);
	}
	kg_patchset_free(&ps);
	kg_patchset_free(&done);
	free(have);
	free(partial);
	return rc;
}

