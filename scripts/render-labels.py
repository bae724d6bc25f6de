"""Renders the README's label-map picture with Blender (headless), through the
add-on itself: File > Import > Slice Stack as Isosurface with Label Map on, one
object per label, named and coloured from the .seg.nrrd's segments.

    blender -b --factory-startup -P scripts/render-labels.py -- ADDON_DIR OUT.png [SEG.seg.nrrd]

ADDON_DIR is the staged add-on folder of a build (build/blender_addon/isomend_import).
Without SEG, a synthetic segmentation is written next to OUT and used (the
README's docs/img/labels-blender.png): an organ of three touching lobes, a
vessel running through it and a tumour on its surface, five labels that share
their boundaries, 112^3 voxels of 1 mm.  Left the labels as imported, right the
same import with each label moved away from the organ's centre.
"""
import math
import os
import sys

import bpy
import numpy as np

args = sys.argv[sys.argv.index("--") + 1:]
addon_dir, out = os.path.abspath(args[0]), os.path.abspath(args[1])
seg = args[2] if len(args) > 2 else None

SEGMENTS = [  # value, name, colour (sRGB 0..1, as 3D Slicer writes it)
    (1, "Right lobe", (0.87, 0.51, 0.40)),
    (2, "Middle lobe", (0.50, 0.68, 0.50)),
    (3, "Left lobe", (0.72, 0.61, 0.86)),
    (4, "Vessel", (0.00, 0.59, 0.81)),
    (5, "Tumour", (0.90, 0.86, 0.27)),
]


def synthetic(path, n=112):
    """array[z, y, x]: an ellipsoid cut into three lobes by two oblique
    planes, a bent tube through it, a ball half sunk into its surface."""
    z, y, x = (a - n / 2 + 0.5 for a in np.mgrid[0:n, 0:n, 0:n].astype(np.float64))
    v = np.zeros((n, n, n), np.uint8)
    organ = (x / 46) ** 2 + (y / 30) ** 2 + (z / 26) ** 2 < 1
    cut = x + 0.35 * z - 0.2 * y
    v[organ & (cut < -12)] = 1
    v[organ & (cut >= -12) & (cut < 16)] = 2
    v[organ & (cut >= 16)] = 3
    # a tube bending through the organ along x (a vessel), out on both sides
    cy, cz = 6 * np.sin(x / 18.0), -4 + 8 * np.cos(x / 25.0)
    v[((y - cy) ** 2 + (z - cz) ** 2 < 5.5 ** 2) & (np.abs(x) < 54)] = 4
    v[(x - 20) ** 2 + (y + 18) ** 2 + (z - 17) ** 2 < 11 ** 2] = 5
    keys = "".join("Segment%d_Name:=%s\nSegment%d_Color:=%g %g %g\nSegment%d_LabelValue:=%d\n"
                   % (i, name, i, *color, i, value) for i, (value, name, color) in enumerate(SEGMENTS))
    with open(path, "wb") as fp:
        fp.write(("NRRD0004\ntype: uint8\ndimension: 3\nsizes: %d %d %d\nspacings: 1 1 1\n"
                  "encoding: raw\n%s\n" % (n, n, n, keys)).encode() + v.tobytes())


if seg is None:
    seg = os.path.splitext(out)[0] + ".seg.nrrd"
    synthetic(seg)

bpy.ops.wm.read_factory_settings(use_empty=True)
sys.path.insert(0, os.path.dirname(addon_dir))
import isomend_import  # noqa: E402  (the staged add-on, as Blender would load it)

isomend_import.register()
scene = bpy.context.scene


def import_labels():
    """The operator as a user runs it; returns the new collection's objects."""
    before = set(bpy.data.collections)
    r = bpy.ops.import_mesh.slice_stack(filepath=seg, label_map=True, pad=True, smooth=True,
                                        unit_scale=0.01)
    assert r == {"FINISHED"}, r
    print(isomend_import.last_import["message"], flush=True)
    (col,) = set(bpy.data.collections) - before
    return list(col.objects)


def box(objs):
    c = np.array([o.matrix_world @ v.co for o in objs for v in o.data.vertices])
    return c.min(0), c.max(0)


# left: the labels as imported; right: the same import moved apart from the
# organ's centre, each label a closed surface of its own
whole = import_labels()
lo, hi = box(whole)
centre, size = (lo + hi) / 2, hi - lo
apart = import_labels()
shift = np.array([1.2 * size[0], 0.0, 0.0])
for o in apart:
    a, b = box([o])
    o.location = tuple(np.array(o.location) + shift + 0.45 * ((a + b) / 2 - centre))
bpy.context.view_layer.update()  # matrix_world follows the new locations
lo, hi = box(whole + apart)
centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo) / 2
target = bpy.data.objects.new("target", None)
scene.collection.objects.link(target)
target.location = centre
cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
scene.collection.objects.link(cam)
cam.data.lens = 35
view = np.array([0.25, -1.0, 0.55])  # from the front and above
cam.location = centre + view / np.linalg.norm(view) * radius * 2.2
track = cam.constraints.new("TRACK_TO")
track.target, track.track_axis, track.up_axis = target, "TRACK_NEGATIVE_Z", "UP_Y"
scene.camera = cam
scene.render.engine = "BLENDER_WORKBENCH"
scene.display.shading.light = "STUDIO"
scene.display.shading.color_type = "MATERIAL"
scene.display.shading.show_cavity = True
scene.render.resolution_x, scene.render.resolution_y = 1400, 620
scene.render.film_transparent = False
scene.world = bpy.data.worlds.new("world")
scene.world.color = (0.9, 0.9, 0.9)
scene.render.filepath = out
bpy.ops.render.render(write_still=True)
