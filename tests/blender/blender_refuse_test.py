"""Runs inside headless Blender (run_blender_tests.py --mode refuse prepares it):
a package whose libraries cannot load here installs and enables, and the
import refuses with a clear message instead of a traceback:

    blender -b --factory-startup -noaudio --python-exit-code 1 \\
        --python blender_refuse_test.py -- refuse.json

refuse.json: {"package", "install", "directory" (a good stack), "expect" (the
message's words)}.  Checks: the add-on enables (registering loads no
library); the operator's method list still lists the thesis methods; the
import raises RuntimeError whose message contains "expect", and leaves no
object or mesh.  run_blender_tests.py checks that no traceback was printed.
"""
import json
import os
import sys

import bpy

spec = json.load(open(sys.argv[sys.argv.index("--") + 1]))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_install  # noqa: E402

name, module = blender_install.install(spec)
bpy.ops.wm.read_homefile(use_empty=True)   # no default cube: any object would be the import's
items = [i[0] for i in module._method_items(None, bpy.context)]
assert items[:3] == ["DMC", "MC", "DURST"], items
try:
    bpy.ops.import_mesh.slice_stack(directory=spec["directory"])
    raise AssertionError("the import did not refuse")
except RuntimeError as exc:
    message = str(exc)
print("refused: %s" % message.strip(), flush=True)
assert spec["expect"] in message, "%r does not say %r" % (message, spec["expect"])
assert len(bpy.data.objects) == 0 and len(bpy.data.meshes) == 0, "the refused import left data behind"
blender_install.uninstall(name)
print("refuse test: passed", flush=True)
