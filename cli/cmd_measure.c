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
#include "kg_pipeline.h"

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

/* The terminal's answers: one line from standard input per prompt. */
static int ask_stdin(void *user, const char *allowed, const char *prompt)
{
	(void)user;
	fputs(prompt, stderr);
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

static void say_stderr(void *user, const char *message)
{
	(void)user;
	fprintf(stderr, "%s\n", message);
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

int kg_cmd_measure(int argc, char **argv)
{
	const char *uri = NULL, *out = NULL, *chart = NULL, *list = NULL, *file = NULL,
	           *id = "1", *white_ref = NULL;
	int single = 0, info_only = 0, yes = 0, resume = 0, check_white = 0, nl = 1;
	double integration_ms = 100, max_age = 600;
	kg_measure_flow m = {0};
	m.ui.ask = ask_stdin;
	m.ui.say = say_stderr;
	kg_measure_flow_init(&m);
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
			if (kg_cli_number(optarg, &integration_ms) || !(integration_ms > 0) ||
			    integration_ms > 4e6)
				return kg_cli_usage_error(usage_measure, "--integration %s: expected "
				                          "milliseconds > 0", optarg);
			break;
		case O_AVERAGE:
			if (kg_cli_int(optarg, 1, 10000, &m.s.acq.scans))
				return kg_cli_usage_error(usage_measure, "--average %s: expected 1-10000",
				                          optarg);
			break;
		case O_BOXCAR:
			if (kg_cli_int(optarg, 0, 100, &m.s.acq.boxcar))
				return kg_cli_usage_error(usage_measure, "--boxcar %s: expected 0-100",
				                          optarg);
			break;
		case O_WHITE_REF: white_ref = optarg; break;
		case O_MAX_AGE:
			if (kg_cli_number(optarg, &max_age) || !(max_age > 0))
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
	kg_patch_list pl = {0};
	int r = 0;
	if ((chart || list || file) && (r = kg_patch_list_load(chart, list, file, &pl, &err)) != 0) {
		kg_patch_list_free(&pl);
		return kg_cli_error(&err, r);
	}
	if ((r = kg_white_reference_load(white_ref, &m.s.white_refl, &err)) != 0) {
		kg_patch_list_free(&pl);
		return kg_cli_error(&err, r);
	}
	m.s.uri = uri;
	m.s.white_ref_path = white_ref;
	m.white_max_age = max_age;
	m.yes = yes;
	if ((r = kg_spectro_open(uri, &m.s.spectro, &err)) != 0) {
		kg_patch_list_free(&pl);
		return device_exit(&err, r);
	}
	if (record && (r = kg_spectro_record_start(m.s.spectro, record, &err)) != 0) {
		kg_spectro_free(&m.s.spectro);
		kg_patch_list_free(&pl);
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
			if (!(r = kg_measure_flow_dark(&m, &err)) && !(r = kg_measure_flow_white(&m, &err)) &&
			    kg_measure_flow_ask(&m, "", "Put the probe on the sample %s.", id) == 'q')
				r = 1;
			if (!r)
				r = kg_measure_flow_sample(&m, id, &s, &err);
			if (!r)
				r = kg_patchset_new(1, KG_PATCH_SPECTRA, &ps, &err);
			if (!r && !(r = kg_patchset_set_id(ps, 0, id, &err))) {
				ps->spectra[0] = s;
				/* A file problem, not the device's. */
				if ((r = kg_measure_flow_write(&m, out, ps, &err)) != 0)
					exit_code = kg_cli_error(&err, r);
			}
			kg_patchset_free(&ps);
		} else if (!r) {
			r = kg_measure_flow_chart(&m, &pl, out, resume, check_white, &err);
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
	kg_patch_list_free(&pl);
	return exit_code;
}
