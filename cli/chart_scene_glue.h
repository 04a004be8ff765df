/* Chart layouts (calib/) as chart scenes (sim/): the one conversion from a
 * kg_chart_layout to the plain geometry kg_sim_chart_render draws, used by
 * `kogei sim chart` (cli/cmd_sim_chart.c). */
#ifndef KG_CLI_CHART_SCENE_GLUE_H
#define KG_CLI_CHART_SCENE_GLUE_H

#include "kg_calib.h"
#include "kg_sim.h"

/* What a card is printed on and with, beyond the layout. */
typedef struct kg_cli_card_options {
	double paper, ink;       /* flat reflectances of the card and of black tag cells */
	double white_level;      /* scale of the built-in test colours (no spectra) */
	const char *spectra_name;/* the spectra's file, for messages */
	int decoy;               /* 1: other tag ids, the colours in reverse order, no
	                          * occluders or glare */
	const char *occlude;     /* NULL, "tags" (two tags) or "patches" (the first two) */
	int glare;               /* a highlight on the middle patch */
} kg_cli_card_options;

/* Everything a card points to, owned here. */
typedef struct kg_cli_card_parts {
	kg_sim_chart_tag *tags;
	unsigned char **bits;
	int ntags;
	kg_sim_chart_patch *patches;
	kg_sim_chart_occluder occ[2];
	kg_sim_chart_glare glare;
} kg_cli_card_parts;

/* The card of a layout: tags upright, their printed footprint carrying the full bit
 * grid (kg_chart_tag_cells, kg_chart_tag_footprint); patches with the spectra matched
 * by SAMPLE_ID to the layout's ids or aliases (every patch must have one), or the
 * built-in test colours when spectra is NULL. The pose is left zero. The card points
 * into parts and into spectra: keep both until the rendering is done, then free
 * parts with kg_cli_card_parts_free (also after a failure). */
int kg_cli_chart_card(const kg_chart_layout *l, const kg_patchset *spectra,
                      const kg_cli_card_options *o, kg_sim_chart_card *card,
                      kg_cli_card_parts *parts, kg_err *err);
void kg_cli_card_parts_free(kg_cli_card_parts *p);

#endif
