"""Renders the README's "From surface to model" picture with Blender (headless):
the raw marching-cubes surface on the left, the cleaned, smoothed and decimated
model on the right, flat shaded so that the triangles show.

    blender -b --factory-startup -P scripts/render-model.py -- RAW.ply MODEL.ply OUT.png

docs/img/model-before-after.png is the T1 MRI head of scripts/get-test-data.sh
(mri_t1_small, Debian's insighttoolkit5-examples):

    isomend extract ~/.cache/isomend/mri_t1_small/tiff --pad --largest 1 -o raw.ply
    isomend extract ~/.cache/isomend/mri_t1_small/tiff --pad --largest 1 --smooth 15 \
        --decimate 0.1 -o model.ply
"""
import math
import sys

import bpy

raw, model, out = sys.argv[sys.argv.index("--") + 1:][:3]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene


def load(path, dx):
    try:  # Blender 4
        bpy.ops.wm.ply_import(filepath=path)
    except AttributeError:  # Blender 3.4
        bpy.ops.import_mesh.ply(filepath=path)
    ob = bpy.context.selected_objects[0]
    ob.data.validate()
    # its bounding box's centre at (dx, 0, 0), the head upright
    bpy.context.view_layer.objects.active = ob
    bpy.ops.object.origin_set(type="ORIGIN_GEOMETRY", center="BOUNDS")
    ob.location = (dx, 0, 0)
    ob.rotation_euler = (math.radians(90), 0, math.radians(180))
    mat = bpy.data.materials.new("m")
    mat.diffuse_color = (0.85, 0.78, 0.70, 1)
    ob.data.materials.append(mat)
    return ob


load(raw, -135)
load(model, 135)
cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
scene.collection.objects.link(cam)
cam.location = (0, -760, 0)
cam.rotation_euler = (math.radians(90), 0, 0)
cam.data.lens = 50
cam.data.clip_end = 10000
scene.camera = cam
scene.render.engine = "BLENDER_WORKBENCH"
scene.display.shading.light = "STUDIO"
for ob in bpy.data.objects:
    if ob.type == "MESH":
        for poly in ob.data.polygons:
            poly.use_smooth = False
scene.display.shading.color_type = "MATERIAL"
scene.render.resolution_x, scene.render.resolution_y = 1400, 620
scene.render.film_transparent = False
scene.render.filepath = out
bpy.ops.render.render(write_still=True)
