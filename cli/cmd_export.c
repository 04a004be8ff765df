#include <getopt.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "kg_gltf.h"

static const char usage_export[] =
	"kogei export --scene SCENE.json -o OBJECT.glb [--photo PHOTO.png]\n"
	"kogei export --scene SCENE.json -o SCENE.xml\n"
	"  Export a scene (docs/render.md, \"format\": \"kogei-scene/1\") for other renderers.\n"
	"  OBJECT.glb: binary glTF 2.0 (docs/render.md, \"Opening the object in Blender and\n"
	"  a web viewer\"; layout in docs/formats.md) for Blender, three.js, model-viewer:\n"
	"  the scene's mesh split into one PBR metallic-roughness material per region\n"
	"  (metals: metallic 1, base colour the normal-incidence reflectance under D65 in\n"
	"  linear sRGB; dielectrics: metallic 0 with their index, KHR_materials_ior and\n"
	"  KHR_materials_specular; regions that are no library material: a neutral grey\n"
	"  named unknown or background), the scene's camera and directional light\n"
	"  (KHR_lights_punctual). --photo: a PNG of the object as photographed, in the\n"
	"  label map's framing (kogei process's photo.png): a second node \"photograph\",\n"
	"  the same mesh textured with it, beside the object. Needs no Embree.\n"
	"  SCENE.xml: the scene for Mitsuba 3 in a spectral variant (as kogei render\n"
	"  --mitsuba; docs/render.md): spectral conductors from the library's n, k, alloys\n"
	"  as blends of their metals, dielectrics as rough plastic, one binary PLY per\n"
	"  material in the folder SCENE/ beside it; untested by a Mitsuba render.";

static int has_suffix(const char *s, const char *suffix)
{
	size_t n = strlen(s), k = strlen(suffix);
	return n >= k && strcasecmp(s + n - k, suffix) == 0;
}

int kg_cmd_export(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"scene", required_argument, NULL, 's'},
		{"output", required_argument, NULL, 'o'},
		{"photo", required_argument, NULL, 'p'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	const char *scene = NULL, *out = NULL, *photo = NULL;
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "o:h", longopts, NULL)) != -1) {
		switch (c) {
		case 's': scene = optarg; break;
		case 'o': out = optarg; break;
		case 'p': photo = optarg; break;
		case 'h': printf("usage: %s\n", usage_export); return KG_EXIT_OK;
		default: fprintf(stderr, "usage: %s\n", usage_export); return KG_EXIT_USAGE;
		}
	}
	if (optind < argc)
		return kg_cli_usage_error(usage_export, "unexpected argument '%s'", argv[optind]);
	if (!scene || !out)
		return kg_cli_usage_error(usage_export, "expected --scene and -o");
	if (has_suffix(out, ".xml")) {
		if (photo)
			return kg_cli_usage_error(usage_export, "--photo: only with a .glb output");
		kg_err err = {{0}};
		kg_scene *s = NULL;
		int ret = kg_scene_load(scene, &s, &err);
		if (!ret)
			ret = kg_scene_write_mitsuba(s, out, 0, &err);
		kg_scene_free(&s);
		return ret ? kg_cli_error(&err, ret) : KG_EXIT_OK;
	}
	if (!has_suffix(out, ".glb"))
		return kg_cli_usage_error(usage_export, "-o %s: expected a file name ending in .glb "
		                          "(binary glTF 2.0) or .xml (Mitsuba 3)", out);
	kg_err err = {{0}};
	kg_gltf_options opt = {.photo_png = photo, .source = scene};
	int ret = kg_gltf_write_scene_file(scene, &opt, out, &err);
	if (ret)
		return kg_cli_error(&err, ret);
	return KG_EXIT_OK;
}
