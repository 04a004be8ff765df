/* The kogei command line: argument parsing and dispatch only. Each command is a
 * function taking its own argv (argv[0] is the command name). Exit codes follow
 * docs/architecture.md: 0 success, 1 bad input, 2 bad usage, 3 device failure. */
#ifndef KG_CLI_H
#define KG_CLI_H

#include <stdint.h>

#include "kg_calib.h"
#include "kg_core.h"

enum { KG_EXIT_OK = 0, KG_EXIT_INPUT = 1, KG_EXIT_USAGE = 2, KG_EXIT_DEVICE = 3 };

typedef struct kg_command {
	const char *name;    /* e.g. "spectra xyz" */
	int (*run)(int argc, char **argv);
	const char *summary;
} kg_command;

/* Print "kogei: <message>" to stderr and return the exit code for an error code. */
int kg_cli_error(const kg_err *err, int code);
/* Print a usage error and return KG_EXIT_USAGE. */
int kg_cli_usage_error(const char *usage, const char *fmt, ...) KG_PRINTF(2, 3);
/* Pairs of an option's name and its value, ending with NULL: the usage error
 * "NAME is required" for the first value that is NULL, else 0. */
int kg_cli_required(const char *usage, ...);
/* 1 if argv holds -h or --help. */
int kg_cli_wants_help(int argc, char **argv);

/* All of TEXT as a finite number: 0, or -1 (empty, trailing text, not a number, out of
 * double's range). */
int kg_cli_number(const char *text, double *out);
/* All of TEXT as a whole number from lo to hi: 0, or -1. *out is set on success only. */
int kg_cli_int(const char *text, int lo, int hi, int *out);
/* An option's value as a number from lo to hi; otherwise the usage error
 * "OPT 'TEXT': expected a number from LO to HI" and KG_EXIT_USAGE. */
int kg_cli_number_option(const char *usage, const char *opt, const char *text, double lo,
                         double hi, double *out);
/* An option's value as a number >= lo (> lo when strict); otherwise the usage error
 * "OPT TEXT: expected a number >= LO" (or "> LO") and KG_EXIT_USAGE. */
int kg_cli_min_option(const char *usage, const char *opt, const char *text, double lo,
                      int strict, double *out);
/* The same for a whole number: "OPT 'TEXT': expected a whole number from LO to HI". */
int kg_cli_int_option(const char *usage, const char *opt, const char *text, int lo, int hi,
                      int *out);
/* --seed: a whole number >= 0 (no sign), else the usage error and KG_EXIT_USAGE. */
int kg_cli_seed_option(const char *usage, const char *text, uint64_t *out);

/* "a:b[:c]" (numbers separated by colons) into up to max finite values; how many, or
 * -1 for anything else (an empty part, trailing text, too many). */
int kg_cli_parse_numbers(const char *text, double *v, int max);
/* Split "a,b,c" in place into at most max names (*n of them); -1 for an empty name or
 * too many. */
int kg_cli_split_names(char *text, char **names, int max, int *n);

/* Parse "start:stop:step" (degrees) into a newly allocated list. */
int kg_cli_parse_range(const char *text, double **values, int *n, kg_err *err);

/* A photograph to estimate or classify: kg_image_read, and a camera raw file's mosaic
 * demosaiced to RGB (kg_demosaic, as chart detect and process do; refused without
 * OpenCV). Other images are returned as read. */
int kg_cli_read_photograph(const char *path, kg_image **out, kg_err *err);

/* The camera identity of an image file inside a kogei session (the capture's camera,
 * pixel format and demosaicing, kg_session_image_identify). An image outside a
 * session gives id->known = 0 and 0; a session that does not list the image's capture
 * is an error. */
int kg_cli_image_identity(const char *image, kg_camera_identity *id, kg_err *err);
/* Before applying a calibration to an image: 0 when the image's camera is the
 * calibration's (a note on stderr when its reading settings differ) or either is
 * unknown (a note that identity was not checked); another camera is refused (err set,
 * KG_EINVAL) unless force, which turns the refusal into a warning. */
int kg_cli_check_camera(const kg_camera_calib *cam, const char *calib_path,
                        const char *image, int force, kg_err *err);

int kg_cmd_console(int argc, char **argv);
extern const char kg_console_usage[];
int kg_cmd_spectra_xyz(int argc, char **argv);
int kg_cmd_model(int argc, char **argv);
int kg_cmd_materials_learn(int argc, char **argv);
int kg_cmd_demo(int argc, char **argv);
int kg_cmd_sim_patches(int argc, char **argv);
int kg_cmd_sim_image(int argc, char **argv);
int kg_cmd_sim_chart(int argc, char **argv);
int kg_cmd_chart_print(int argc, char **argv);
int kg_cmd_chart_detect(int argc, char **argv);
int kg_cmd_calib_reference(int argc, char **argv);
int kg_cmd_calib_camera(int argc, char **argv);
int kg_cmd_estimate(int argc, char **argv);
int kg_cmd_classify(int argc, char **argv);
int kg_cmd_bench(int argc, char **argv);
int kg_cmd_measure(int argc, char **argv);
int kg_cmd_devices(int argc, char **argv);
int kg_cmd_acquire(int argc, char **argv);
int kg_cmd_render(int argc, char **argv);
int kg_cmd_export(int argc, char **argv);
int kg_cmd_process(int argc, char **argv);
int kg_cmd_report(int argc, char **argv);
int kg_cmd_deposit(int argc, char **argv);
int kg_cmd_collection(int argc, char **argv);

#endif
