"""Measures the add-on's import time on a ~1M-triangle surface (README figure).

    blender -b --factory-startup -noaudio --python-exit-code 1 \\
        --python tests/blender/measure_import.py -- <build>/blender_addon [N]

Writes a gyroid volume of N^3 u8 samples (default 160) as N TIFF slices into a
temporary folder, imports it with bpy.ops.import_mesh.slice_stack (DMC, pad,
smooth normals) and prints the total time and the time spent inside the
wrapper (read + extract) versus building the Blender mesh.  Not a ctest test
(it takes a few seconds and ~1 GB); run it by hand.
"""
import os
import sys
import tempfile
import time

import bpy
import numpy as np

args = sys.argv[sys.argv.index("--") + 1:]
sys.path.insert(0, args[0])  # <build>/blender_addon: holds the staged isomend_import package
n = int(args[1]) if len(args) > 1 else 160
import isomend_import  # noqa: E402

isomend_import.register()
iso = isomend_import.isomend

with tempfile.TemporaryDirectory() as tmp:
    i = np.arange(n, dtype=np.float32)
    s = 2 * np.pi / 24.0
    z, y, x = np.meshgrid(i * s, i * s, i * s, indexing="ij", sparse=True)
    f = np.sin(x) * np.cos(y) + np.sin(y) * np.cos(z) + np.sin(z) * np.cos(x)
    vol = np.clip(np.round(127.5 + 100 * f), 0, 255).astype(np.uint8)
    folder = os.path.join(tmp, "gyroid")
    os.makedirs(folder)
    try:
        import tifffile
        for k in range(n):
            tifffile.imwrite(os.path.join(folder, "g_%04d.tif" % k), vol[k])
    except ImportError:
        sys.exit("tifffile is needed to write the test stack")
    t0 = time.perf_counter()
    core = iso.extract_source(folder, iso=127.5, pad=True)
    t_core = time.perf_counter() - t0
    times = {}
    for label, opts in (("gradient normals", dict(smooth=True, gradient_normals=True)),
                        ("smooth shading", dict(smooth=True, gradient_normals=False)),
                        ("flat", dict(smooth=False))):
        bpy.ops.wm.read_homefile(use_empty=True)
        t0 = time.perf_counter()
        bpy.ops.import_mesh.slice_stack(directory=folder, use_suggested_iso=False, iso=127.5, pad=True,
                                        **opts)
        times[label] = time.perf_counter() - t0
    obj = bpy.context.active_object
    print("MEASURE %d^3 u8 slices: %d vertices, %d triangles; wrapper read+extract %.2f s; import: %s"
          % (n, len(obj.data.vertices), len(obj.data.polygons), t_core,
             ", ".join("%s %.2f s" % kv for kv in times.items())))
