"""Render a kogei glTF (.glb) in Blender with Cycles on the CPU, under the light and from
the camera of the kogei scene it came from.

usage: blender -b --factory-startup --python blender_render.py -- \
           --glb OBJECT.glb --scene SCENE.json --raw OUT.f32 [--png OUT.png]
           [--samples N] [--seed N] [--threads N] [--width W --height H] [--opaque 1]

The scene (kogei-scene/1) gives the camera (position, look_at, up, vertical fov_deg,
width, height), the directional light (direction towards the light, intensity) and a
uniform environment (intensity). Their illuminant must be D65: it is the white of
Blender's scene-linear space (Rec. 709 primaries), so the light is (1, 1, 1) there.
Units are kogei's image scale (Y = 1 for a white diffuser lit at intensity 1):
  - the environment: world colour (1, 1, 1) at strength = intensity (a uniform
    radiance L lights a white diffuser to radiance L in both renderers);
  - the sun: strength = pi x intensity (Cycles' sun strength is the irradiance in
    W/m^2, a white Lambertian surface facing it has radiance strength / pi), angle 0
    (a point-like sun, as kogei's directional light);
  - Cycles: box pixel filter 1 px (kogei jitters uniformly in the pixel), 4 bounces
    (kogei's default), no denoising, no clamping.
The glb's own camera, light and environment backdrop (the node "kogei environment")
are removed (tests/render/blender_import.py renders with them instead). The scene must be in kogei's frame
(+z up): the glTF importer turns glTF's +y up back into Blender's +z up.

--raw: the render in linear scene-referred Rec. 709 RGB and alpha, float32, rows from
the top, after a one-line ASCII header "KOGEI-BLENDER-RAW 1 <width> <height> 4\n".
--png: the same through the Standard view transform (sRGB, no film look), 8 bit; the
background is black (transparent film) unless --opaque 1 shows the sky there (the alpha
of --raw is then 1 everywhere).
"""
import json
import math
import struct
import sys

import bpy
from mathutils import Matrix, Vector


def parse(argv):
    argv = argv[argv.index("--") + 1:] if "--" in argv else []
    opt = {"samples": 16, "seed": 1, "threads": 2, "png": None, "width": 0, "height": 0,
           "opaque": 0}
    i = 0
    while i < len(argv):
        key = argv[i].lstrip("-")
        if key not in ("glb", "scene", "raw", "png", "samples", "seed", "threads", "width",
                       "height", "opaque") or i + 1 >= len(argv):
            raise SystemExit("blender_render.py: bad argument %r" % argv[i])
        val = argv[i + 1]
        opt[key] = int(val) if key in ("samples", "seed", "threads", "width", "height",
                                             "opaque") else val
        i += 2
    for k in ("glb", "scene", "raw"):
        if k not in opt:
            raise SystemExit("blender_render.py: --%s is required" % k)
    return opt


def need_d65(obj, what):
    ill = obj.get("illuminant", "D65")
    if ill != "D65":
        raise SystemExit("blender_render.py: %s illuminant %r: only D65 (Blender's white) "
                         "is supported" % (what, ill))


def main():
    opt = parse(sys.argv)
    scene_json = json.load(open(opt["scene"]))
    cam_j = scene_json["camera"]
    width = opt["width"] or cam_j["width"]
    height = opt["height"] or cam_j["height"]

    # Debian 12's Blender 3.4.1 glTF importer uses numpy.bool, an alias NumPy 1.24 (the
    # numpy it runs with) removed: restore the alias, which is the builtin bool
    import numpy
    if "bool" not in numpy.__dict__:
        numpy.bool = bool

    # an empty scene, then the object
    bpy.ops.object.select_all(action="SELECT")
    bpy.ops.object.delete()
    bpy.ops.import_scene.gltf(filepath=opt["glb"])
    for ob in list(bpy.data.objects):
        if ob.type in ("CAMERA", "LIGHT") or ob.name.startswith("kogei environment"):
            bpy.data.objects.remove(ob, do_unlink=True)
    sc = bpy.context.scene

    # the camera: Blender's looks along its -z with +y up
    pos = Vector(cam_j["position"])
    fwd = (Vector(cam_j["look_at"]) - pos).normalized()
    up = Vector(cam_j.get("up", [0, 0, 1]))
    right = fwd.cross(up).normalized()
    cup = right.cross(fwd).normalized()
    rot = Matrix((right, cup, -fwd)).transposed()
    cam_data = bpy.data.cameras.new("kogei-camera")
    cam_data.sensor_fit = "VERTICAL"
    cam_data.angle_y = math.radians(cam_j["fov_deg"])
    cam_data.clip_start = 1e-3
    cam_data.clip_end = 1e4
    cam = bpy.data.objects.new("kogei-camera", cam_data)
    cam.matrix_world = Matrix.Translation(pos) @ rot.to_4x4()
    sc.collection.objects.link(cam)
    sc.camera = cam

    # the directional light
    if "light" in scene_json:
        lj = scene_json["light"]
        need_d65(lj, "light")
        d = Vector(lj["direction"]).normalized()
        sun_data = bpy.data.lights.new("kogei-sun", type="SUN")
        sun_data.energy = math.pi * lj.get("intensity", 1.0)
        sun_data.color = (1.0, 1.0, 1.0)
        sun_data.angle = 0.0
        sun = bpy.data.objects.new("kogei-sun", sun_data)
        # a sun shines along its -z: +z towards the light
        z = d
        x = Vector((1, 0, 0)) if abs(z.x) < 0.9 else Vector((0, 1, 0))
        x = (x - z * x.dot(z)).normalized()
        y = z.cross(x)
        sun.matrix_world = Matrix((x, y, z)).transposed().to_4x4()
        sc.collection.objects.link(sun)

    # the environment: uniform
    world = bpy.data.worlds.new("kogei-world")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    strength = 0.0
    if "environment" in scene_json:
        ej = scene_json["environment"]
        need_d65(ej, "environment")
        if "image" in ej:
            raise SystemExit("blender_render.py: image environments are not supported")
        strength = ej.get("intensity", 1.0)
    bg.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bg.inputs["Strength"].default_value = strength
    sc.world = world

    # Cycles on the CPU, fixed seed
    sc.render.engine = "CYCLES"
    cy = sc.cycles
    cy.device = "CPU"
    cy.samples = opt["samples"]
    cy.seed = opt["seed"]
    cy.use_denoising = False
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
    sc.render.resolution_x = width
    sc.render.resolution_y = height
    sc.render.resolution_percentage = 100
    sc.render.pixel_aspect_x = sc.render.pixel_aspect_y = 1.0
    sc.render.film_transparent = not opt["opaque"]
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0.0
    sc.view_settings.gamma = 1.0

    # linear float through OpenEXR, read back into the raw file
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
    import os
    os.remove(exr)
    if opt["png"]:
        sc.render.image_settings.file_format = "PNG"
        sc.render.image_settings.color_depth = "8"
        sc.render.image_settings.color_mode = "RGB"
        # the rendered result, saved through the view transform (no second render)
        bpy.data.images["Render Result"].save_render(opt["png"])
    print("blender_render.py: %d x %d, %d samples, seed %d -> %s" % (w, h, opt["samples"],
                                                                    opt["seed"], opt["raw"]))


main()
