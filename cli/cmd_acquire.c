/* kogei acquire: one capture from a camera into a session (acquire/, docs/acquire.md). */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "kg_acquire.h"
#include "kg_calib.h"
#include "kg_pipeline.h"

static const char usage_acquire[] =
	"kogei acquire --camera URI --out SESSION --kind chart|object|dark|flat|background\n"
	"              [options]\n"
	"  Take one capture: N frames averaged (mean and per-pixel variance, float32 TIFF),\n"
	"  dark-subtracted and flat-field corrected, demosaiced when Bayer, and recorded\n"
	"  into the session directory with its manifest (SESSION/session.json).\n"
	"  URI: v4l2:/dev/videoN, aravis:ADDRESS, libcamera:ID, gphoto2:MODEL|PORT,\n"
	"       files:DIR or files:DIR/PATTERN (raw files, TIFF, PNG: one frame per file,\n"
	"       e.g. files:shoot/chart_*.CR3), replay:SESSION[#CAPTURE],\n"
	"       sim:[IMAGE][?key=value&...] (see `kogei devices`, docs/cameras.md)\n"
	"  --name NAME          capture name (default <kind>-NNNN, the next free number)\n"
	"  --frames N           frames averaged (default 10; files: every file)\n"
	"  --exposure US|auto   exposure in microseconds, or auto: the exposure helper sets\n"
	"                       it so the brightest patch sits at --target, then locks it\n"
	"                       (default: the camera's exposure, auto exposure off)\n"
	"  --target LEVEL       the helper's level, 0..1 of full scale (default 0.8)\n"
	"  --layout L           the chart's layout (kogei-chart/1 JSON, .cht, or a bundled\n"
	"                       layout's name, e.g. colorchecker24-frame), recorded with a\n"
	"                       chart capture for `kogei process`; the helper measures the\n"
	"                       brightest patch of it; without it a robust\n"
	"                       high percentile of the blurred frame\n"
	"  --gain G             gain in the camera's unit (default: the camera's)\n"
	"  --format PIXFMT      mono8..16, bayer8..16, bayer_rggb12, rgb8, rgb16, yuyv, mjpeg\n"
	"  --roi WxH+X+Y        region of the sensor\n"
	"  --dark NAME|none     dark capture to subtract (default: the session's latest\n"
	"                       dark with the same exposure, gain, format and size)\n"
	"  --flat NAME|latest|none  flat capture to divide by (normalised to its mean);\n"
	"                       default latest: the session's newest flat of this camera,\n"
	"                       format and size (none when it has none); a NAME older than\n"
	"                       that newest one is used with a warning\n"
	"  --timeout-ms T       wait per frame (default 2000 + twice the exposure)\n"
	"  --max-dropped N      dropped frames tolerated (default 0)\n"
	"  --force-nonlinear    accept YUYV or MJPEG (display-encoded, MJPEG lossy: not\n"
	"                       for measurements; averaged as decoded R'G'B')\n"
	"  --no-record          do not store the raw frames (no replay possible)\n"
	"  --meta KEY=VALUE     object record, repeatable: accession, title, operator,\n"
	"                       lighting, notes or a free key of [A-Za-z0-9_.-]{1,64};\n"
	"                       the value UTF-8, at most 4096 bytes, no control characters\n"
	"                       and no invisible or bidirectional format characters;\n"
	"                       stored as the capture's \"meta\" in SESSION/session.json\n"
	"  Exit 0 ok, 1 bad input, 2 bad usage, 3 the camera failed (timeouts, dropped or\n"
	"  incomplete frames: the counts are printed and nothing is added to the session).";

/* ---- terminal --------------------------------------------------------------------- */

static void progress(void *user, const char *name, int i, int n, double fps)
{
	int tty = *(int *)user;
	if (tty) {
		fprintf(stderr, "\r%s: frame %d/%d  %.1f fps ", name, i, n, fps);
		if (i == n)
			fputc('\n', stderr);
	} else if (i == n || i % (n >= 10 ? n / 10 : 1) == 0) {
		fprintf(stderr, "%s: frame %d/%d  %.1f fps\n", name, i, n, fps);
	}
	fflush(stderr);
}

static void note(void *user, const char *message)
{
	(void)user;
	if (!strncmp(message, "warning: ", 9))
		fprintf(stderr, "kogei: %s\n", message);
	else
		fprintf(stderr, "kogei: note: %s\n", message);
}

/* ---- options ---------------------------------------------------------------------- */

static int parse_roi(const char *text, kg_frame_format *f)
{
	int w, h, x, y, n = 0;
	if (sscanf(text, "%dx%d+%d+%d%n", &w, &h, &x, &y, &n) != 4 || text[n] || w < 1 ||
	    h < 1 || x < 0 || y < 0)
		return kg_cli_usage_error(usage_acquire,
		                          "--roi '%s': expected WxH+X+Y (e.g. 640x480+16+8)", text);
	f->width = w;
	f->height = h;
	f->offset_x = x;
	f->offset_y = y;
	return 0;
}

/* Exit code for a camera or session error (a full disk, KG_ENOSPC, is never the
 * camera's). */
static int exit_for(const kg_err *err, int code, int device)
{
	fprintf(stderr, "kogei: %s\n", err->msg[0] ? err->msg : "failed");
	return device && code != KG_ENOSPC ? KG_EXIT_DEVICE : KG_EXIT_INPUT;
}

static void print_summary(const kg_capture_result *r, const kg_capture_options *o,
                          const char *session, int ncaptures)
{
	char gain[48] = "";
	if (isfinite(r->gain))
		snprintf(gain, sizeof(gain), ", gain %.6g", r->gain);
	printf("%s: %d frames, %s%s%s %d bits %dx%d+%d+%d, exposure %.6g us%s\n", r->name,
	       o->frames, kg_pixfmt_name(r->format.pixfmt), r->format.cfa[0] ? " " : "",
	       r->format.cfa, r->format.bits, r->format.width, r->format.height,
	       r->format.offset_x, r->format.offset_y, r->exposure_us, gain);
	if (r->nsteps)
		printf("  exposure helper: %d step(s), locked at %.6g us (level %.4f, target %.3f)\n",
		       r->nsteps, r->steps[r->nsteps - 1].exposure_us, r->steps[r->nsteps - 1].level,
		       o->target);
	printf("  clipped %.4f %%, under-exposed %.2f %%, max %.4f, p99 %.4f, p50 %.4f\n",
	       100 * r->clipped_fraction, 100 * r->stats.underexposed_fraction, r->stats.max,
	       r->stats.p99, r->stats.p50);
	if (kg_saturation_below(&r->saturation, 1.0 - 0.5 / r->saturation.steps)) {
		char where[256];
		kg_saturation_format(&r->saturation,
		                     r->format.cfa[0] && r->saturation.channels == 4 ? r->format.cfa
		                                                                     : "RGB",
		                     where, sizeof(where));
		printf("  saturation found from the data below full scale: %s\n", where);
	}
	printf("  stream: %llu completed, %llu dropped, %llu incomplete, %llu failed, %llu "
	       "timeouts, %llu packets resent, %llu packets missing\n",
	       (unsigned long long)r->stream.completed, (unsigned long long)r->stream.dropped,
	       (unsigned long long)r->stream.incomplete, (unsigned long long)r->stream.failed,
	       (unsigned long long)r->stream.timeouts, (unsigned long long)r->stream.resent,
	       (unsigned long long)r->stream.missing_packets);
	printf("  dark: %s, flat: %s\n", r->dark[0] ? r->dark : "none",
	       r->flat[0] ? r->flat : "none");
	printf("  wrote %s/captures/%s/mean.tif, variance.tif%s; %s/%s holds %d capture(s)\n",
	       session, r->name, r->rgb ? ", rgb.tif" : "", session, KG_SESSION_MANIFEST,
	       ncaptures);
}

static void decref_p(json_t **p) { json_decref(*p); }

int kg_cmd_acquire(int argc, char **argv)
{
	if (kg_cli_wants_help(argc, argv)) {
		printf("usage: %s\n", usage_acquire);
		return KG_EXIT_OK;
	}
	kg_capture_options o;
	kg_capture_options_default(&o);
	const char *uri = NULL, *out = NULL, *kind = NULL, *layout = NULL;
	int have_target = 0, have_frames = 0;
	enum { O_NAME = 256, O_FRAMES, O_EXPOSURE, O_TARGET, O_LAYOUT, O_GAIN, O_FORMAT, O_ROI,
	       O_DARK, O_FLAT, O_TIMEOUT, O_MAX_DROPPED, O_FORCE, O_NO_RECORD, O_KIND, O_META };
	static const struct option opts[] = {
		{"camera", required_argument, NULL, 'c'},
		{"out", required_argument, NULL, 'o'},
		{"kind", required_argument, NULL, O_KIND},
		{"name", required_argument, NULL, O_NAME},
		{"frames", required_argument, NULL, O_FRAMES},
		{"exposure", required_argument, NULL, O_EXPOSURE},
		{"target", required_argument, NULL, O_TARGET},
		{"layout", required_argument, NULL, O_LAYOUT},
		{"gain", required_argument, NULL, O_GAIN},
		{"format", required_argument, NULL, O_FORMAT},
		{"roi", required_argument, NULL, O_ROI},
		{"dark", required_argument, NULL, O_DARK},
		{"flat", required_argument, NULL, O_FLAT},
		{"timeout-ms", required_argument, NULL, O_TIMEOUT},
		{"max-dropped", required_argument, NULL, O_MAX_DROPPED},
		{"force-nonlinear", no_argument, NULL, O_FORCE},
		{"no-record", no_argument, NULL, O_NO_RECORD},
		{"meta", required_argument, NULL, O_META},
		{NULL, 0, NULL, 0},
	};
	optind = 1;
	opterr = 0;
	int opt, r = 0;
	int n = 0; /* set on success only; GCC cannot see errors are nonzero */
	kg_err err = {{0}};
	json_t *meta __attribute__((cleanup(decref_p))) = json_object();
	o.meta = meta;
	while (!r && (opt = getopt_long(argc, argv, ":c:o:", opts, NULL)) != -1) {
		switch (opt) {
		case 'c': uri = optarg; break;
		case 'o': out = optarg; break;
		case O_KIND: kind = optarg; break;
		case O_NAME: o.name = optarg; break;
		case O_FRAMES:
			r = kg_cli_int_option(usage_acquire, "--frames", optarg, 1, 1000000, &o.frames);
			have_frames = 1;
			break;
		case O_EXPOSURE:
			if (!strcmp(optarg, "auto"))
				o.auto_exposure = 1;
			else
				r = kg_cli_number_option(usage_acquire, "--exposure", optarg, 1e-3, 1e9,
				                         &o.exposure_us);
			break;
		case O_TARGET:
			r = kg_cli_number_option(usage_acquire, "--target", optarg, 0.01, 0.99, &o.target);
			have_target = 1;
			break;
		case O_LAYOUT: layout = optarg; break;
		case O_GAIN:
			r = kg_cli_number_option(usage_acquire, "--gain", optarg, -1e6, 1e6, &o.gain);
			break;
		case O_FORMAT:
			if (kg_pixfmt_parse(optarg, &o.format.pixfmt, &o.format.bits, o.format.cfa, &err))
				r = kg_cli_usage_error(usage_acquire, "--format: %s", err.msg);
			break;
		case O_ROI: r = parse_roi(optarg, &o.format); break;
		case O_DARK: o.dark = optarg; break;
		case O_FLAT: o.flat = optarg; break;
		case O_TIMEOUT:
			r = kg_cli_int_option(usage_acquire, "--timeout-ms", optarg, 1, 3600000,
			                      &o.timeout_ms);
			break;
		case O_MAX_DROPPED:
			if (!(r = kg_cli_int_option(usage_acquire, "--max-dropped", optarg, 0, 1000000000,
			                            &n)))
				o.max_dropped = n;
			break;
		case O_FORCE: o.force_nonlinear = 1; break;
		case O_NO_RECORD: o.record = 0; break;
		case O_META:
			if (kg_meta_parse_arg(meta, "--meta", optarg, &err))
				r = kg_cli_usage_error(usage_acquire, "%s", err.msg);
			break;
		case ':':
			r = kg_cli_usage_error(usage_acquire, "option %s needs a value", argv[optind - 1]);
			break;
		default:
			r = kg_cli_usage_error(usage_acquire, "unknown option '%s'", argv[optind - 1]);
			break;
		}
	}
	if (r)
		return r;
	if (optind < argc)
		return kg_cli_usage_error(usage_acquire, "unexpected argument '%s'", argv[optind]);
	if (!uri)
		return kg_cli_usage_error(usage_acquire, "--camera URI is required");
	if (!out)
		return kg_cli_usage_error(usage_acquire, "--out SESSION is required");
	if (!kind)
		return kg_cli_usage_error(usage_acquire, "--kind chart|object|dark|flat|background is required");
	if (kg_capture_kind_parse(kind, &o.kind, &err))
		return kg_cli_usage_error(usage_acquire, "--kind: %s", err.msg);
	if (o.name && !kg_name_is_safe(o.name, KG_CAPTURE_NAME_MAX))
		return kg_cli_usage_error(usage_acquire,
		                          "--name '%s': expected 1 to %d letters, digits, '.', '_' or "
		                          "'-', not starting with '.'",
		                          o.name, KG_CAPTURE_NAME_MAX - 1);
	if (have_target && !o.auto_exposure)
		return kg_cli_usage_error(usage_acquire, "--target: only with --exposure auto");
	if (layout && !o.auto_exposure && o.kind != KG_CAPTURE_CHART)
		return kg_cli_usage_error(usage_acquire, "--layout: only with --exposure auto or "
		                          "--kind chart");
	if (o.kind == KG_CAPTURE_DARK && o.auto_exposure)
		return kg_cli_usage_error(usage_acquire,
		                          "--exposure auto: a dark has no light to meter; give the "
		                          "exposure of the captures it is for");
	if (o.kind == KG_CAPTURE_DARK && o.dark && strcmp(o.dark, "none"))
		return kg_cli_usage_error(usage_acquire, "--dark: does not apply to --kind dark");
	if ((o.kind == KG_CAPTURE_DARK || o.kind == KG_CAPTURE_FLAT) && o.flat &&
	    strcmp(o.flat, "none"))
		return kg_cli_usage_error(usage_acquire, "--flat: does not apply to --kind %s", kind);

	kg_chart_level cm = {0};
	kg_chart_layout *layout_loaded = NULL;
	if (layout) {
		if ((r = kg_chart_layout_load(layout, &layout_loaded, &err)))
			return kg_cli_error(&err, r);
		cm.layout = layout_loaded;
		kg_chart_detect_options_default(&cm.opt);
		o.measure = o.auto_exposure ? kg_chart_brightest_patch : NULL;
		o.measure_user = &cm;
		o.chart_layout = layout;
	}
	char measure_name[96];
	snprintf(measure_name, sizeof(measure_name), "brightest patch of chart %s",
	         cm.layout ? cm.layout->name : "");
	o.measure_name = measure_name;
	int tty = isatty(STDERR_FILENO);
	o.progress = progress;
	o.progress_user = &tty;
	o.note = note;

	kg_session *s = NULL;
	kg_camera *camera = NULL;
	kg_capture_result res;
	memset(&res, 0, sizeof(res));
	int code = kg_session_open(out, &s, &err);
	if (code) {
		r = exit_for(&err, code, 0);
		goto done;
	}
	if (kg_session_foreign(s)[0]) {
		char shown[1024];
		fprintf(stderr, "kogei: note: %s also holds files kogei did not write (%s): kept, "
		        "not part of the session's record\n", out,
		        kg_text_visible(kg_session_foreign(s), SIZE_MAX, shown, sizeof(shown)));
	}
	code = kg_camera_open(uri, &camera, &err);
	if (code) {
		r = exit_for(&err, code,
		             code == KG_ENODEV || code == KG_EIO || code == KG_ETIMEDOUT ||
		                 code == KG_ENOTSUP);
		goto done;
	}
	/* Photographs already taken (files:): every file unless --frames says otherwise. */
	long available = kg_camera_frames_available(camera);
	if (!have_frames && available > 0)
		o.frames = available > 1000000 ? 1000000 : (int)available;
	if (have_frames && available >= 0 && o.frames > available) {
		r = kg_cli_usage_error(usage_acquire, "--frames %d: %s holds %ld frame(s)", o.frames,
		                       uri, available);
		goto done;
	}
	code = kg_capture_run(s, camera, &o, &res, &err);
	if (code) {
		r = exit_for(&err, code, res.device_failure);
		goto done;
	}
	print_summary(&res, &o, out,
	              (int)json_array_size(json_object_get(kg_session_manifest(s), "captures")));
done:
	kg_capture_result_clear(&res);
	kg_camera_free(&camera);
	kg_session_free(&s);
	kg_chart_layout_free(&layout_loaded);
	return r;
}
