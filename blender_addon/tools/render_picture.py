"""Renders the README picture of the add-on: a real MRI slice stack imported
with File > Import > Slice Stack as Isosurface, rendered headless (Workbench).

    blender -b --factory-startup -noaudio --python-exit-code 1 \\
        --python blender_addon/tools/render_picture.py -- \\
        <build>/blender_addon STACK_FOLDER OUT.png [OUT_CLOSEUP.png]

STACK_FOLDER: e.g. the TIFF slices of scripts/get-test-data.sh mri_t1_small
(128x128x62 T1 MRI, 2 x 2 x 3 mm, ImageJ spacing in the files).  The import
uses the operator's defaults (suggested iso, DMC, closed at the border,
gradient normals).  The optional second picture, closer, colours red the
triangles the thesis method added to mend holes (origin "mend").
"""
import math
import os
import sys

import bpy
import numpy as np
from mathutils import Vector

args = sys.argv[sys.argv.index("--") + 1:]
if len(args) < 3:
    sys.exit("usage: ... -- <build>/blender_addon STACK_FOLDER OUT.png [OUT_CLOSEUP.png]")
sys.path.insert(0, args[0])
import isomend_import  # noqa: E402

isomend_import.register()
stack, out_png = os.path.abspath(args[1]), os.path.abspath(args[2])
closeup_png = os.path.abspath(args[3]) if len(args) > 3 else None

bpy.ops.wm.read_homefile(use_empty=True)
result = bpy.ops.import_mesh.slice_stack(directory=stack)
assert result == {"FINISHED"}, result
obj = bpy.context.active_object
me = obj.data
print("imported %s: %d vertices, %d triangles, %d mending, iso %g, dimensions %s m"
      % (obj.name, len(me.vertices), len(me.polygons), obj["isomend_mending_triangles"],
         obj["isomend_iso"], tuple(round(d, 4) for d in obj.dimensions)))

# Axial slices: x = image column (left-right), y = image row (row 0, the top of
# the displayed image, is the front of the head), z = slice (feet to head for
# this scan, whose slices run from the top of the head down).  With Blender's z up and its front view looking along +y, the
# imported object faces the front camera; slices stored head to feet put it
# upside down, so it is turned 180 degrees about x (a rotation of the object,
# never a mirror; FLIP=0 in the environment skips it for feet-to-head scans).
if os.environ.get("FLIP", "1") == "1":
    obj.rotation_euler = (math.pi, 0, 0)
bpy.context.view_layer.update()
corners = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
lo = Vector([min(c[i] for c in corners) for i in range(3)])
hi = Vector([max(c[i] for c in corners) for i in range(3)])
centre, size = (lo + hi) / 2, max(hi - lo)

scene = bpy.context.scene
scene.render.engine = "BLENDER_WORKBENCH"
scene.display.shading.light = "STUDIO"
scene.display.shading.color_type = "MATERIAL"  # per-face colours from the materials
scene.display.shading.show_cavity = True
scene.display.shading.show_specular_highlight = True
scene.render.resolution_x, scene.render.resolution_y = 640, 480
scene.render.film_transparent = False
scene.view_settings.view_transform = "Standard"  # Filmic would wash the colours out
scene.world = bpy.data.worlds.new("world")
scene.world.color = (0.62, 0.66, 0.72)
scene.render.image_settings.file_format = "PNG"
scene.render.image_settings.color_mode = "RGB"
scene.render.image_settings.compression = 100

skin = bpy.data.materials.new("skin")
skin.diffuse_color = (0.85, 0.72, 0.62, 1.0)
mend = bpy.data.materials.new("mending")
mend.diffuse_color = (0.9, 0.1, 0.1, 1.0)
me.materials.append(skin)
me.materials.append(mend)

cam_data = bpy.data.cameras.new("camera")
cam = bpy.data.objects.new("camera", cam_data)
scene.collection.objects.link(cam)
scene.camera = cam


def shoot(direction, distance, target, lens, path):
    cam.location = target + direction.normalized() * distance
    cam.rotation_euler = (target - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam_data.lens = lens
    cam_data.clip_start, cam_data.clip_end = distance * 0.01, distance * 10
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    print("wrote " + path)


view = Vector((0.9, 1.0, 0.2))  # between the face (+y after the turn) and the left ear (+x), slightly above
shoot(view, size * 2.6, centre, 50, out_png)

if closeup_png:
    # colour the mending triangles: the wrapper's triangle order is the mesh's
    paths = [stack]
    core = isomend_import.isomend.extract_source(paths, pad=True, normals=False)
    assert core.triangle_count == len(me.polygons)
    mat_index = (core.origins == isomend_import.isomend.ORIGIN_MEND).astype(np.int32)
    me.polygons.foreach_set("material_index", mat_index)
    me.update()
    shoot(view, size * 1.7, centre + Vector((0, size * 0.1, size * 0.05)), 50, closeup_png)
