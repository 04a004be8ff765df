#include <getopt.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"
#include "kg_calib.h"
#include "kg_devices.h"

static const char usage_measure[] =
	"kogei measure --spectro URI (--single | --chart LAYOUT | --patches ID,ID,... |\n"
	"              --patches-file FILE | --info) [-o|--out FILE.cgats] [options]\n"
	"  Reflectance readings with a USB spectrometer: a dark reference (probe covered),\n"
	"  a white reference (the white standard), then the samples:\n"
	"  R = (S - D) / (W - D) x R_white, resampled to 400-700 nm every 5 nm.\n"
	"  URI: usbspec:<vid>:<pid>[:<serial>] (hex, e.g. usbspec:2457:101e) or\n"
	"       sim:<spectra.cgats> (a simulated instrument measuring those spectra) or\n"
	"       replay:<recording> (plays back a --record recording).\n"
	"  --single           measure one spot (its SAMPLE_ID from --id, default 1)\n"
	"  --chart LAYOUT     guide through the patches of a chart layout (kogei-chart/1\n"
	"                     JSON, ArgyllCMS .cht, or a bundled layout's name such as\n"
	"                     colorchecker24-frame), telling where each patch is\n"
	"  --patches IDS      the same with a comma-separated list of patch ids\n"
	"  --patches-file F   the same with the SAMPLE_IDs of a CGATS file (.ti1/.ti3)\n"
	"  --info             print the instrument's identity and calibration and exit\n"
	"  --integration MS   integration time in milliseconds (default 100)\n"
	"  --average N        scans averaged per reading (default 3)\n"
	"  --boxcar HALF      boxcar smoothing half-width in pixels (default 0)\n"
	"  --white-ref FILE   certified reflectance of the white standard (CGATS; default\n"
	"                     flat 0.99)\n"
	"  --white-max-age S  warn when the white reference is older than S seconds (600)\n"
	"  --check-white      measure the white again at the end and report its drift\n"
	"  --no-nonlinearity  do not apply the device's nonlinearity correction\n"
	"  --yes              do not wait for the operator (scripts, tests)\n"
	"  --resume           continue an interrupted chart from OUT.partial\n"
	"  --record FILE      also write the raw reads to FILE (also on failure), a\n"
	"                     recording that --spectro replay:FILE plays back\n"
	"  Each prompt reads one line: Enter (or m) measures, r redoes the last patch,\n"
	"  w measures the white again, q stops (what was measured stays in OUT.partial).\n"
	"  Output: CGATS with SAMPLE_ID SPEC_400 ... SPEC_700, the instrument, its serial\n"
	"  and the integration time. Exit 3 when the device fails; OUT is then not written.";

/* Above this relative change of the white's signal a warning is printed. */
#define WHITE_DRIFT_LIMIT 0.02

typedef struct measure_ctx {
	kg_measure_session s; /* the instrument, settings, dark and white references */
	double white_max_age;
	int yes;
	int white_age_warned;
} measure_ctx;

/* Errors from the device layer: bad input and a reading that cannot be measured as
 * set up (KG_ERANGE: saturated, outside the nonlinearity's range) are 1, everything
 * else is the device. */
static int device_exit(const kg_err *err, int code)
{
	kg_cli_error(err, code);
	return code == KG_EINVAL || code == KG_ENOENT || code == KG_ENOMEM || code == KG_ERANGE
	               ? KG_EXIT_INPUT
	               : KG_EXIT_DEVICE;
}

/* Ask the operator; returns 'm' (measure), 'r', 'w' or 'q' (also at end of input). */
static int ask(const measure_ctx *m, const char *allowed, const char *fmt, ...)
	KG_PRINTF(3, 4);
static int ask(const measure_ctx *m, const char *allowed, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	vfprintf(stderr, fmt, ap);
	va_end(ap);
	if (m->yes) {
		fputc('\n', stderr);
		return 'm';
	}
	for (;;) {
		fprintf(stderr, " [Enter=measure%s%s q=quit] ", strchr(allowed, 'r') ? " r=redo last" : "",
		        strchr(allowed, 'w') ? " w=white again" : "");
		fflush(stderr);
		char line[64];
		if (!fgets(line, sizeof(line), stdin)) {
			fputc('\n', stderr);
			return 'q';
		}
		char c = line[0] == '\n' || line[0] == '\r' ? 'm' : line[0];
		if (c == 'q' || c == 'm' || (c != 0 && strchr(allowed, c)))
			return c;
		fprintf(stderr, "kogei: '%c' is not an answer here\n", c);
	}
}

/* The session's warnings (saturation, pixels without white signal). */
static void warn_stderr(void *user, const char *message)
{
	(void)user;
	fprintf(stderr, "warning: %s\n", message);
}

static int measure_dark(measure_ctx *m, kg_err *err)
{
	if (ask(m, "", "Cover the probe (dark reference).") == 'q')
		return 1;
	kg_spectro_reading_clear(&m->s.dark);
	return kg_measure_reading(&m->s, "dark", "dark reference", &m->s.dark, err);
}

/* Measure the white; with a previous white, report how far it drifted. */
static int measure_white(measure_ctx *m, kg_err *err)
{
	if (ask(m, "", "Put the probe on the white standard (white reference).") == 'q')
		return 1;
	kg_spectro_reading w = {0};
	int r = kg_measure_reading(&m->s, "white", "white reference", &w, err);
	if (r)
		return r;
	if (m->s.white.n) {
		double d = kg_white_drift(&m->s.dark, &m->s.white, &w);
		fprintf(stderr, "white reference changed by %+.2f %% since the last one\n", 100 * d);
		if (fabs(d) > WHITE_DRIFT_LIMIT)
			fprintf(stderr,
			        "warning: the white reference drifted by %+.1f %% (more than %.0f %%): "
			        "lamp or probe changed; readings since the last white may be off\n",
			        100 * d, 100 * WHITE_DRIFT_LIMIT);
	}
	kg_spectro_reading_clear(&m->s.white);
	m->s.white = w;
	m->white_age_warned = 0;
	return 0;
}

static int measure_sample(measure_ctx *m, const char *id, kg_spectrum *out, kg_err *err)
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	double age = ts.tv_sec - m->s.white.when;
	if (age > m->white_max_age && !m->white_age_warned) {
		fprintf(stderr,
		        "warning: the white reference is %.0f s old (limit %.0f s): answer w to "
		        "measure it again\n", age, m->white_max_age);
		m->white_age_warned = 1;
	}
	return kg_measure_sample(&m->s, id, out, err);
}

/* Output keywords: instrument, serial, settings. */
static int write_result(const measure_ctx *m, const char *path, kg_patchset *ps, kg_err *err)
{
	return kg_measure_write(&m->s, path, ps, "kogei measure", NULL, err);
}

/* The patches to measure, with where each is on the chart. */
typedef struct patch_list {
	int n;
	char **ids;
	char **places;
} patch_list;

static void patch_list_free(patch_list *l)
{
	for (int i = 0; i < l->n; i++) {
		free(l->ids[i]);
		free(l->places[i]);
	}
	free(l->ids);
	free(l->places);
	memset(l, 0, sizeof(*l));
}

static int patch_list_add(patch_list *l, const char *id, const char *place)
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

static int load_patches(const char *chart, const char *list, const char *file, patch_list *l,
                        kg_err *err)
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

static void print_info(const kg_spectro_info *info)
{
	printf("model: %s\nserial: %s\nbackend: %s\npixels: %d\n", info->model, info->serial,
	       info->backend, info->npixels);
	printf("wavelength coefficients: %.9g %.9g %.9g %.9g\n", info->wl_coeffs[0],
	       info->wl_coeffs[1], info->wl_coeffs[2], info->wl_coeffs[3]);
	printf("wavelength range: %.3f - %.3f nm\n", kg_spectro_wavelength(info, 0),
	       kg_spectro_wavelength(info, info->npixels - 1));
	if (info->dark_first >= 0)
		printf("electrical dark pixels: %d-%d\n", info->dark_first, info->dark_last);
	printf("nonlinearity order: %d\n", info->nl_order);
	if (info->nl_order >= 0) {
		printf("nonlinearity coefficients:");
		for (int k = 0; k <= info->nl_order; k++)
			printf(" %.9g", info->nl_coeffs[k]);
		printf("\n");
	}
	printf("integration range: %u - %u us\nsaturation: %.0f counts\nusb speed: %s\n",
	       info->min_integration_us, info->max_integration_us, info->saturation,
	       info->high_speed ? "high" : "full");
}

/* The guided chart: patches in order, progress, redo, white again, partial file. */
static int run_chart(measure_ctx *m, const patch_list *pl, const char *out, int resume,
                     int check_white, kg_err *err)
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
			fprintf(stderr, "resuming: %d of %d patches already measured in %s\n",
			        done->n, pl->n, partial);
	}
	int rc = r;
	if (!rc)
		rc = measure_dark(m, err);
	if (!rc)
		rc = measure_white(m, err);
	int last = -1, ndone = 0;
	for (int i = 0; i < pl->n; i++)
		ndone += have[i];
	int i = 0;
	while (!rc && i < pl->n) {
		if (have[i]) {
			i++;
			continue;
		}
		int c = ask(m, last >= 0 ? "rw" : "w", "[%d/%d] Put the probe on patch %s%s%s.",
		            ndone + 1, pl->n, pl->ids[i], pl->places[i][0] ? " " : "",
		            pl->places[i]);
		int target = i;
		if (c == 'q') {
			rc = 1;
			break;
		}
		if (c == 'w') {
			rc = measure_white(m, err);
			continue;
		}
		if (c == 'r') {
			target = last;
			fprintf(stderr, "Put the probe on patch %s again.\n", pl->ids[target]);
		}
		kg_spectrum s;
		if ((rc = measure_sample(m, pl->ids[target], &s, err)) != 0)
			break;
		ps->spectra[target] = s;
		if (!have[target])
			ndone++;
		have[target] = 1;
		last = target;
		fprintf(stderr, "measured %s (%d of %d)\n", pl->ids[target], ndone, pl->n);
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
			rc = write_result(m, partial, sofar, err);
		kg_patchset_free(&sofar);
	}
	if (!rc && check_white) {
		kg_spectro_reading before = m->s.white;
		m->s.white = (kg_spectro_reading){0};
		rc = measure_white(m, err);
		if (!rc) {
			double d = kg_white_drift(&m->s.dark, &before, &m->s.white);
			fprintf(stderr, "white reference drift over the chart: %+.2f %%\n", 100 * d);
		}
		if (!rc && fabs(kg_white_drift(&m->s.dark, &before, &m->s.white)) > WHITE_DRIFT_LIMIT)
			fprintf(stderr, "warning: the white reference drifted by more than %.0f %% "
			                "during the chart: consider measuring it again\n",
			        100 * WHITE_DRIFT_LIMIT);
		kg_spectro_reading_clear(&before);
	}
	if (!rc) {
		rc = write_result(m, out, ps, err);
		if (!rc)
			unlink(partial);
	} else if (ndone > 0) {
		fprintf(stderr, "kogei: %d of %d patches are saved in %s; run again with --resume "
		                "to continue\n", ndone, pl->n, partial);
	}
	kg_patchset_free(&ps);
	kg_patchset_free(&done);
	free(have);
	free(partial);
	return rc;
}

int kg_cmd_measure(int argc, char **argv)
{
	const char *uri = NULL, *out = NULL, *chart = NULL, *list = NULL, *file = NULL,
	           *id = "1", *white_ref = NULL;
	int single = 0, info_only = 0, yes = 0, resume = 0, check_white = 0, nl = 1;
	double integration_ms = 100, max_age = 600;
	measure_ctx m = {0};
	kg_acquire_options_default(&m.s.acq);
	m.s.acq.scans = 3;
	enum { O_SINGLE = 256, O_CHART, O_PATCHES, O_PATCHES_FILE, O_INFO, O_INTEGRATION,
	       O_AVERAGE, O_BOXCAR, O_WHITE_REF, O_MAX_AGE, O_CHECK_WHITE, O_NO_NL, O_YES,
	       O_RESUME, O_ID, O_RECORD };
	const char *record = NULL;
	static const struct option opts[] = {
		{"spectro", required_argument, NULL, 's'},
		{"out", required_argument, NULL, 'o'},
		{"single", no_argument, NULL, O_SINGLE},
		{"chart", required_argument, NULL, O_CHART},
		{"patches", required_argument, NULL, O_PATCHES},
		{"patches-file", required_argument, NULL, O_PATCHES_FILE},
		{"info", no_argument, NULL, O_INFO},
		{"id", required_argument, NULL, O_ID},
		{"integration", required_argument, NULL, O_INTEGRATION},
		{"average", required_argument, NULL, O_AVERAGE},
		{"boxcar", required_argument, NULL, O_BOXCAR},
		{"white-ref", required_argument, NULL, O_WHITE_REF},
		{"white-max-age", required_argument, NULL, O_MAX_AGE},
		{"check-white", no_argument, NULL, O_CHECK_WHITE},
		{"no-nonlinearity", no_argument, NULL, O_NO_NL},
		{"yes", no_argument, NULL, O_YES},
		{"resume", no_argument, NULL, O_RESUME},
		{"record", required_argument, NULL, O_RECORD},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	int c;
	char *end;
	optind = 1;
	while ((c = getopt_long(argc, argv, "s:o:h", opts, NULL)) != -1) {
		switch (c) {
		case 's': uri = optarg; break;
		case 'o': out = optarg; break;
		case O_SINGLE: single = 1; break;
		case O_CHART: chart = optarg; break;
		case O_PATCHES: list = optarg; break;
		case O_PATCHES_FILE: file = optarg; break;
		case O_INFO: info_only = 1; break;
		case O_ID: id = optarg; break;
		case O_INTEGRATION:
			integration_ms = strtod(optarg, &end);
			if (*end || !(integration_ms > 0) || integration_ms > 4e6)
				return kg_cli_usage_error(usage_measure, "--integration %s: expected "
				                          "milliseconds > 0", optarg);
			break;
		case O_AVERAGE:
			m.s.acq.scans = (int)strtol(optarg, &end, 10);
			if (*end || m.s.acq.scans < 1 || m.s.acq.scans > 10000)
				return kg_cli_usage_error(usage_measure, "--average %s: expected 1-10000",
				                          optarg);
			break;
		case O_BOXCAR:
			m.s.acq.boxcar = (int)strtol(optarg, &end, 10);
			if (*end || m.s.acq.boxcar < 0 || m.s.acq.boxcar > 100)
				return kg_cli_usage_error(usage_measure, "--boxcar %s: expected 0-100",
				                          optarg);
			break;
		case O_WHITE_REF: white_ref = optarg; break;
		case O_MAX_AGE:
			max_age = strtod(optarg, &end);
			if (*end || !(max_age > 0))
				return kg_cli_usage_error(usage_measure, "--white-max-age %s: expected "
				                          "seconds > 0", optarg);
			break;
		case O_CHECK_WHITE: check_white = 1; break;
		case O_NO_NL: nl = 0; break;
		case O_YES: yes = 1; break;
		case O_RESUME: resume = 1; break;
		case O_RECORD: record = optarg; break;
		case 'h': puts(usage_measure); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_measure, "bad option");
		}
	}
	if (optind != argc)
		return kg_cli_usage_error(usage_measure, "unexpected argument '%s'", argv[optind]);
	if (!uri)
		return kg_cli_usage_error(usage_measure, "--spectro URI is required");
	int modes = single + info_only + !!chart + !!list + !!file;
	if (modes != 1)
		return kg_cli_usage_error(usage_measure, "expected exactly one of --single, --chart, "
		                          "--patches, --patches-file, --info");
	if (!info_only && !out)
		return kg_cli_usage_error(usage_measure, "--out FILE.cgats is required");
	if (!nl)
		m.s.acq.corrections &= ~(unsigned)KG_CORRECT_NONLINEARITY;

	kg_err err = {{0}};
	patch_list pl = {0};
	int r = 0;
	if ((chart || list || file) && (r = load_patches(chart, list, file, &pl, &err)) != 0) {
		patch_list_free(&pl);
		return kg_cli_error(&err, r);
	}
	if ((r = kg_white_reference_load(white_ref, &m.s.white_refl, &err)) != 0) {
		patch_list_free(&pl);
		return kg_cli_error(&err, r);
	}
	m.s.uri = uri;
	m.s.white_ref_path = white_ref;
	m.s.warn = warn_stderr;
	m.white_max_age = max_age;
	m.yes = yes;
	if ((r = kg_spectro_open(uri, &m.s.spectro, &err)) != 0) {
		patch_list_free(&pl);
		return device_exit(&err, r);
	}
	if (record && (r = kg_spectro_record_start(m.s.spectro, record, &err)) != 0) {
		kg_spectro_free(&m.s.spectro);
		patch_list_free(&pl);
		return kg_cli_error(&err, r);
	}
	const kg_spectro_info *info = kg_spectro_get_info(m.s.spectro);
	int exit_code = KG_EXIT_OK;
	if (info_only) {
		print_info(info);
	} else {
		double us = floor(integration_ms * 1000 + 0.5);
		r = us > UINT32_MAX
		        ? kg_fail(&err, KG_EINVAL, "--integration %g ms is too long", integration_ms)
		        : kg_spectro_set_integration(m.s.spectro, (uint32_t)us, &err);
		fprintf(stderr, "%s %s, integration %.3f ms, %d scan(s) averaged\n", info->model,
		        info->serial, integration_ms, m.s.acq.scans);
		if (!r && single) {
			kg_patchset *ps = NULL;
			kg_spectrum s;
			if (!(r = measure_dark(&m, &err)) && !(r = measure_white(&m, &err)) &&
			    ask(&m, "", "Put the probe on the sample %s.", id) == 'q')
				r = 1;
			if (!r)
				r = measure_sample(&m, id, &s, &err);
			if (!r)
				r = kg_patchset_new(1, KG_PATCH_SPECTRA, &ps, &err);
			if (!r && !(r = kg_patchset_set_id(ps, 0, id, &err))) {
				ps->spectra[0] = s;
				/* A file problem, not the device's. */
				if ((r = write_result(&m, out, ps, &err)) != 0)
					exit_code = kg_cli_error(&err, r);
			}
			kg_patchset_free(&ps);
		} else if (!r) {
			r = run_chart(&m, &pl, out, resume, check_white, &err);
		}
		if (r > 0) {
			fprintf(stderr, "kogei: stopped by the operator; %s not written\n", out);
			exit_code = KG_EXIT_INPUT;
		} else if (r && exit_code == KG_EXIT_OK) {
			exit_code = device_exit(&err, r);
		}
	}
	int nrec = 0;
	if (record && (r = kg_spectro_record_finish(m.s.spectro, &nrec, &err)) != 0) {
		int e = kg_cli_error(&err, r);
		exit_code = exit_code ? exit_code : e;
	} else if (record)
		fprintf(stderr, "recorded %d raw reads in %s\n", nrec, record);
	kg_measure_session_clear(&m.s);
	kg_spectro_free(&m.s.spectro);
	patch_list_free(&pl);
	return exit_code;
}
