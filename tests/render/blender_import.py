"""Render a kogei glTF (.glb) in Blender as File > Import gives it: the file's own camera,
light and environment backdrop, nothing set from kogei's scene.

usage: blender -b --factory-startup --python blender_import.py -- \
           --glb OBJECT.glb --raw OUT.f32 --width W --height H [--png OUT.png]
           [--samples N] [--seed N] [--threads N]

What it does besides importing: it empties the factory scene first (its cube, lamp and
camera) and makes its world black (the factory world is a grey of 0.05: the object is
to be lit by what the file carries alone), imports with the importer's defaults (the
standard lighting mode: lux / 683 = W/m^2), makes the file's camera the scene's camera
(Blender renders from the scene's camera; the importer does not choose one), and sets
the output: W x H (the importer ignores the camera's aspectRatio), Cycles on the CPU
with the settings of blender_render.py (box filter 1 px, 4 bounces, no denoising, no
clamping). The light, its intensity and colour, the camera's pose and field of view,
the materials and the environment are the file's as imported.

--raw: linear scene-referred Rec. 709 RGB and alpha, float32, rows from the top, after
a one-line header "KOGEI-BLENDER-RAW 1 <width> <height> 4\n" (blender_compare.py reads
it); transparent film, so alpha tells the object (1) from the backdrop (its coverage).
Prints the imported lights' strengths, the backdrop's emission and the camera."""
import os
import struct
import sys

import bpy


def parse(argv):
    argv = argv[argv.index("--") + 1:] if "--" in argv else []
    opt = {"samples": 16, "seed": 1, "threads": 2, "png": None}
    keys = ("glb", "raw", "png", "samples", "seed", "threads", "width", "height")
    ints = ("samples", "seed", "threads", "width", "height")
    i = 0
    while i < len(argv):
        key = argv[i].lstrip("-")
        if key not in keys or i + 1 >= len(argv):
            raise SystemExit("blender_import.py: bad argument %r" % argv[i])
        opt[key] = int(argv[i + 1]) if key in ints else argv[i + 1]
        i += 2
    for k in ("glb", "raw", "width", "height"):
        if k not in opt:
            raise SystemExit("blender_import.py: --%s is required" % k)
    return opt


def main():
    opt = parse(sys.argv)
    # Debian 12's Blender 3.4.1 glTF importer uses numpy.bool, an alias NumPy 1.24 (the
    # numpy it runs with) removed: restore the alias, which is the builtin bool
    import numpy
    if "bool" not in numpy.__dict__:
        numpy.bool = bool

    bpy.ops.object.select_all(action="SELECT")
    bpy.ops.object.delete()
    sc = bpy.context.scene
    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    sc.world = world

    bpy.ops.import_scene.gltf(filepath=opt["glb"])
    cams = [ob for ob in sc.objects if ob.type == "CAMERA"]
    if len(cams) != 1:
        raise SystemExit("blender_import.py: %d cameras in %s: expected the file's one"
                         % (len(cams), opt["glb"]))
    sc.camera = cams[0]
    for ob in sc.objects:
        if ob.type == "LIGHT":
            print("blender_import.py: light %r: %s, strength %.6g, colour %s" % (
                ob.name, ob.data.type, ob.data.energy, tuple(round(c, 4) for c in ob.data.color)))
    for mat in bpy.data.materials:
        if mat.use_nodes and "environment" in mat.name:
            p = mat.node_tree.nodes.get("Principled BSDF")
            if p:
                print("blender_import.py: backdrop %r: emission strength %.6g, alpha %.6g" % (
                    mat.name, p.inputs["Emission Strength"].default_value,
                    p.inputs["Alpha"].default_value))
    print("blender_import.py: camera %r, vertical fov %.3f rad" % (cams[0].name,
                                                                  cams[0].data.angle_y))

    sc.render.engine = "CYCLES"
    cy = sc.cycles
    cy.device = "CPU"
    cy.samples = opt["samples"]
    cy.seed = opt["seed"]
    cy.use_denoising = False  # Debian's Cycles has no OpenImageDenoise
    cy.use_adaptive_sampling = False
    cy.pixel_filter_type = "BOX"
    cy.filter_width = 1.0
    cy.max_bounces = 4
    cy.diffuse_bounces = 4
    cy.glossy_bounces = 4
    cy.transmission_bounces = 4
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.caustics_reflective = True
    cy.blur_glossy = 0.0
    sc.render.threads_mode = "FIXED"
    sc.render.threads = opt["threads"]
    sc.render.resolution_x = opt["width"]
    sc.render.resolution_y = opt["height"]
    sc.render.resolution_percentage = 100
    sc.render.film_transparent = True
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0.0
    sc.view_settings.gamma = 1.0

    exr = opt["raw"] + ".exr"
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.image_settings.color_mode = "RGBA"
    sc.render.filepath = exr
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(exr)
    img.colorspace_settings.name = "Linear"
    px = list(img.pixels)
    w, h = img.size
    with open(opt["raw"], "wb") as f:
        f.write(b"KOGEI-BLENDER-RAW 1 %d %d 4\n" % (w, h))
        for row in range(h - 1, -1, -1):  # Blender's rows run from the bottom
            f.write(struct.pack("<%df" % (4 * w), *px[row * w * 4:(row + 1) * w * 4]))
    os.remove(exr)
    if opt["png"]:
        sc.render.image_settings.file_format = "PNG"
        sc.render.image_settings.color_depth = "8"
        sc.render.image_settings.color_mode = "RGB"
        bpy.data.images["Render Result"].save_render(opt["png"])
    print("blender_import.py: %d x %d, %d samples, seed %d -> %s" % (w, h, opt["samples"],
                                                                    opt["seed"], opt["raw"]))


main()
