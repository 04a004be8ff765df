#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "kg_config.h"

static const kg_command commands[] = {
	{"acquire", kg_cmd_acquire, "record camera frames into a session (chart, object, dark, flat, background)"},
	{"console", kg_cmd_console, "the operator's web console: live view, guided capture, processing"},
	{"measure", kg_cmd_measure, "reflectance readings with a USB spectrometer (single spot or chart)"},
	{"spectra xyz", kg_cmd_spectra_xyz, "CIE XYZ and CIELAB of the spectra in a CGATS file"},
	{"model", kg_cmd_model, "reflectance of a material over wavelength and incidence angle"},
	{"materials learn", kg_cmd_materials_learn, "templates from photographs of reference coupons"},
	{"sim patches", kg_cmd_sim_patches, "simulated camera readings of reflectance spectra"},
	{"sim image", kg_cmd_sim_image, "simulated camera image of a chart and material samples"},
	{"sim chart", kg_cmd_sim_chart, "simulated photograph of a chart layout with its truth"},
	{"chart print", kg_cmd_chart_print, "printable AprilTag frame of a chart layout at true size"},
	{"chart detect", kg_cmd_chart_detect, "find a chart in a photograph and measure its patches"},
	{"calib reference", kg_cmd_calib_reference, "fit B, M and the other methods on a measured chart"},
	{"calib camera", kg_cmd_calib_camera, "fit M2 for a site camera from its chart photograph"},
	{"estimate", kg_cmd_estimate, "per-pixel 61-band reflectance cube of an image"},
	{"classify", kg_cmd_classify, "per-pixel material labels among the declared materials"},
	{"render", kg_cmd_render, "render a scene's mesh and materials under any light (Embree)"},
	{"export", kg_cmd_export, "a scene as binary glTF 2.0 for Blender and web viewers"},
	{"process", kg_cmd_process, "a recorded session to calibration, material maps, scenes and report"},
	{"report", kg_cmd_report, "write a processed session's report.html again from its process.json"},
	{"deposit", kg_cmd_deposit, "a BagIt bag of a processed session for a repository; --verify re-checks one"},
	{"collection", kg_cmd_collection, "every session of a collection (CSV) here or on Slurm; run, status"},
	{"bench", kg_cmd_bench, "speed against error of every estimation method"},
	{"demo", kg_cmd_demo, "run the whole pipeline on the bundled default"},
	{"devices", kg_cmd_devices, "camera and spectrometer backends built, spectrometers attached"},
};

/* A message that may quote what the user or a file gave, printed so that the terminal
 * shows every byte (control sequences and format characters escaped, text.h). */
static void print_visible(FILE *f, const char *msg)
{
	static char shown[4 * sizeof(((kg_err *)0)->msg) + 16];
	fputs(kg_text_visible(msg, SIZE_MAX, shown, sizeof(shown)), f);
}

int kg_cli_error(const kg_err *err, int code)
{
	fputs("kogei: ", stderr);
	print_visible(stderr, err && err->msg[0] ? err->msg : "failed");
	fputc('\n', stderr);
	if (code == KG_ENODEV || code == KG_ETIMEDOUT)
		return KG_EXIT_DEVICE;
	return KG_EXIT_INPUT;
}

int kg_cli_usage_error(const char *usage, const char *fmt, ...)
{
	va_list ap;
	char msg[2048];
	fputs("kogei: ", stderr);
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	print_visible(stderr, msg);
	fprintf(stderr, "\nusage: %s\n", usage);
	return KG_EXIT_USAGE;
}

int kg_cli_wants_help(int argc, char **argv)
{
	for (int i = 1; i < argc; i++) {
		if (strcmp(argv[i], "--") == 0)
			break;
		if (strcmp(argv[i], "-h") == 0 || strcmp(argv[i], "--help") == 0)
			return 1;
	}
	return 0;
}

static void usage(FILE *fp)
{
	fprintf(fp, "usage: kogei [--help] [--version] COMMAND [ARGS...]\n\n"
	            "kogei measures spectral reflectance and materials of craft objects.\n\n"
	            "Commands:\n");
	for (size_t i = 0; i < sizeof(commands) / sizeof(commands[0]); i++)
		fprintf(fp, "  %-22s %s\n", commands[i].name, commands[i].summary);
	fprintf(fp, "\n'kogei COMMAND --help' describes a command.\n"
	            "Exit status: 0 success, 1 bad input, 2 bad usage, 3 device failure.\n");
}

int main(int argc, char **argv)
{
	if (argc < 2) {
		usage(stderr);
		return KG_EXIT_USAGE;
	}
	if (strcmp(argv[1], "--version") == 0) {
		printf("kogei %s\n", KG_VERSION);
		return KG_EXIT_OK;
	}
	if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 ||
	    strcmp(argv[1], "help") == 0) {
		usage(stdout);
		return KG_EXIT_OK;
	}
	/* Match the longest command name made of one or two words. */
	for (int words = 2; words >= 1; words--) {
		if (argc < 1 + words)
			continue;
		char name[128];
		if (words == 2)
			snprintf(name, sizeof(name), "%s %s", argv[1], argv[2]);
		else
			snprintf(name, sizeof(name), "%s", argv[1]);
		for (size_t i = 0; i < sizeof(commands) / sizeof(commands[0]); i++)
			if (strcmp(commands[i].name, name) == 0)
				return commands[i].run(argc - words, argv + words);
	}
	/* A group name alone ("kogei spectra") lists its subcommands. */
	int shown = 0;
	for (size_t i = 0; i < sizeof(commands) / sizeof(commands[0]); i++) {
		size_t n = strlen(argv[1]);
		if (strncmp(commands[i].name, argv[1], n) == 0 && commands[i].name[n] == ' ') {
			if (!shown)
				fprintf(stderr, "kogei %s: expected a subcommand:\n", argv[1]);
			fprintf(stderr, "  kogei %-20s %s\n", commands[i].name, commands[i].summary);
			shown = 1;
		}
	}
	if (!shown) {
		char arg[256];
		fprintf(stderr, "kogei: unknown command '%s' (see 'kogei --help')\n",
		        kg_text_visible(argv[1], 60, arg, sizeof(arg)));
	}
	return KG_EXIT_USAGE;
}
