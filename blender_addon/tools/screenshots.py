"""Screenshots of the add-on in Blender's interface, for the README:

    xvfb-run -a -s "-screen 0 1280x800x24" blender --factory-startup -noaudio \\
        --python blender_addon/tools/screenshots.py -- <build>/blender_addon STACK_FOLDER OUT_DIR

Writes OUT_DIR/blender-dialog.png (File > Import > Slice Stack as Isosurface:
the file browser on STACK_FOLDER with the operator's options) and
OUT_DIR/blender-result.png (the imported stack in the viewport, with the
report in the status bar).  Timers drive the steps; the files are written by
bpy.ops.screen.screenshot, or with ISOMEND_SCREENSHOT=x11 by ImageMagick's
`import -window root` (the whole X screen: Blender 4.3 under Xvfb with
Mesa's software OpenGL reads back a black window), after closing 4.3's
first-start splash with `xdotool key Escape`.
"""
import os
import subprocess
import sys
import time

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
sys.path.insert(0, args[0])
stack, out_dir = os.path.abspath(args[1]), os.path.abspath(args[2])
import isomend_import  # noqa: E402

isomend_import.register()
state = {"step": 0, "t0": time.time()}


def main_window():
    return bpy.context.window_manager.windows[0]


def override(win, area_type=None):
    areas = [a for a in win.screen.areas if area_type is None or a.type == area_type]
    area = max(areas, key=lambda a: a.width * a.height)
    region = [r for r in area.regions if r.type == "WINDOW"][0]
    return bpy.context.temp_override(window=win, area=area, region=region)


def screenshot(win, path):
    if os.environ.get("ISOMEND_SCREENSHOT") == "x11":
        subprocess.run(["import", "-window", "root", path], check=True)
    else:
        with override(win):
            bpy.ops.screen.screenshot(filepath=path)


def tick():
    try:
        return step()
    except Exception as exc:
        print("screenshots failed: %r" % exc, flush=True)
        os._exit(1)


def step():
    s = state["step"]
    state["step"] += 1
    if time.time() - state["t0"] > 120:
        print("screenshots: timed out", flush=True)
        os._exit(1)
    if s == 0:
        if os.environ.get("ISOMEND_SCREENSHOT") == "x11":
            # Blender 4.2+ opens its first-start splash: Esc closes it
            subprocess.run(["xdotool", "key", "Escape"], check=False)
        # delete the default cube, open the file browser of the operator on the stack
        for obj in list(bpy.data.objects):
            if obj.type == "MESH":
                bpy.data.objects.remove(obj)
        with override(main_window(), "VIEW_3D"):
            bpy.ops.import_mesh.slice_stack("INVOKE_DEFAULT", directory=stack + "/",
                                            filepath=stack + "/")
        return 2.0
    if s == 1:
        wins = bpy.context.window_manager.windows
        win = wins[-1]  # the file browser opens in a window of its own
        screenshot(win, os.path.join(out_dir, "blender-dialog.png"))
        with override(win, "FILE_BROWSER"):
            bpy.ops.file.cancel()
        return 1.0
    if s == 2:
        with override(main_window(), "VIEW_3D"):
            r = bpy.ops.import_mesh.slice_stack("EXEC_DEFAULT", directory=stack)
        obj = bpy.context.view_layer.objects.active
        if FLIP:
            obj.rotation_euler = (3.14159265, 0, 0)
        bpy.context.view_layer.update()
        with override(main_window(), "VIEW_3D"):
            # the face looks towards +y after the turn: Blender's back view, then
            # orbit towards the left ear and slightly from above
            bpy.ops.view3d.view_axis(type="BACK")
            bpy.ops.view3d.view_orbit(angle=0.75, type="ORBITRIGHT")
            bpy.ops.view3d.view_orbit(angle=0.2, type="ORBITUP")
            bpy.ops.view3d.view_selected()
        print("imported", r, flush=True)
        return 2.0
    if s == 3:
        screenshot(main_window(), os.path.join(out_dir, "blender-result.png"))
        print("screenshots written to " + out_dir, flush=True)
        os._exit(0)
    return None


FLIP = os.environ.get("FLIP", "1") == "1"
bpy.app.timers.register(tick, first_interval=2.0)
