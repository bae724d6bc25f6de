"""The interactive (modal) import, in Blender's interface under Xvfb:

    xvfb-run -a blender --factory-startup -noaudio --enable-event-simulate \\
        --python blender_modal_test.py -- cases.json      (see run_blender_tests.py --mode gui)

1. an import started as from the file browser (modal_ui=True) returns
   {'RUNNING_MODAL'} at once, runs on the C library's own thread while the
   interface keeps running (no Python thread: Blender does not support them,
   so the test fails if one exists while the import runs), and ends with one
   object whose counts equal `isomend extract`'s;
2. an import of a larger stack followed by a simulated Esc ends cancelled,
   with a warning and no object or mesh left behind;
3. RACE_CYCLES more imports of the larger stack, Esc pressed at once in every
   other one (it must end cancelled, nothing left) and at a random moment in
   the others (cancelled with nothing left, or finished with the same mesh as
   every other finished one).  Under Xvfb Blender's loop runs about twice a
   second, so a timer's Esc mostly arrives after the 0.1 s import: the cancels
   at random moments inside the work are tested in C (tests/io/test_io_api.c);
4. an import still running when Blender loads another file (which ends every
   modal operator) is abandoned: its thread is stopped and joined, and
   last_import says it was cancelled.
Timers drive the steps; the exit status is set with os._exit because an
exception inside a timer does not reach --python-exit-code.
"""
import json
import os
import random
import sys
import threading
import time

import bpy

spec_path = sys.argv[sys.argv.index("--") + 1]
with open(spec_path) as fp:
    SPEC = json.load(fp)


def fail(message):
    print("FAIL: " + message, flush=True)
    os._exit(1)


sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_install  # noqa: E402

try:
    ADDON, module = blender_install.install(SPEC)
except AssertionError as exc:
    fail("the add-on could not be installed: %s" % exc)

case = SPEC["cases"][0]
state = {"step": "start", "t0": time.time(), "cycle": 0, "ended": {"CANCELLED": 0, "FINISHED": 0}}
RACE_CYCLES = 12
rng = random.Random(7)


def window_override():
    win = bpy.context.window_manager.windows[0]
    area = max(win.screen.areas, key=lambda a: a.width * a.height)
    return bpy.context.temp_override(window=win, area=area)


def start(directory, **kwargs):
    module.last_import.clear()
    with window_override():
        r = bpy.ops.import_mesh.slice_stack('EXEC_DEFAULT', directory=directory, modal_ui=True, **kwargs)
    # the import has just started: a worker in Python would be running now
    if r == {"RUNNING_MODAL"} and threading.active_count() != 1:
        fail("a Python thread runs during the import: %s" % threading.enumerate())
    return r


def start_case():
    p = case["params"]
    iso = {} if p["use_suggested_iso"] else {"iso": p["iso"]}
    return start(case["directory"], use_suggested_iso=p["use_suggested_iso"], method=p["method"],
                 spacing=p["spacing"], unit_scale=p["unit_scale"], pad=p["pad"], **iso)


def tick():
    try:
        return step()
    except Exception as exc:  # a failure inside a timer would otherwise be ignored
        fail("%s: %r" % (state["step"], exc))


def step():
    now = time.time()
    if now - state["t0"] > 240:
        fail("timed out in step %s" % state["step"])
    if state["step"] == "start":
        for obj in list(bpy.data.objects):
            bpy.data.objects.remove(obj)
        r = start_case()
        if r != {"RUNNING_MODAL"}:
            fail("modal import returned %s, expected RUNNING_MODAL" % r)
        state["step"] = "wait_import"
        return 0.1
    if state["step"] in ("wait_import", "wait_cancel", "race_wait") and threading.active_count() != 1:
        fail("a Python thread runs during the import: %s" % threading.enumerate())
    if state["step"] == "wait_import":
        if not module.last_import:
            return 0.1
        if module.last_import["status"] != "FINISHED":
            fail("modal import ended %s" % module.last_import)
        obj = bpy.data.objects.get(case["name"])
        if obj is None:
            fail("no object %r after the modal import" % case["name"])
        cli = case["cli"]
        if (len(obj.data.vertices), len(obj.data.polygons)) != (cli["vertices"], cli["triangles"]):
            fail("modal import: %d vertices, %d triangles; CLI %d, %d"
                 % (len(obj.data.vertices), len(obj.data.polygons), cli["vertices"], cli["triangles"]))
        print("modal import ok: %s" % module.last_import["message"], flush=True)
        bpy.data.objects.remove(obj)
        for me in list(bpy.data.meshes):
            bpy.data.meshes.remove(me)
        r = start(SPEC["big"])
        if r != {"RUNNING_MODAL"}:
            fail("second modal import returned %s" % r)
        bpy.context.window_manager.windows[0].event_simulate(type='ESC', value='PRESS')
        state["step"] = "wait_cancel"
        return 0.1
    if state["step"] == "wait_cancel":
        if not module.last_import:
            return 0.1
        if module.last_import["status"] != "CANCELLED" or "cancelled" not in module.last_import["message"]:
            fail("Esc did not cancel the import: %s" % module.last_import)
        if len(bpy.data.objects) or len(bpy.data.meshes):
            fail("a cancelled import left %d objects, %d meshes" % (len(bpy.data.objects), len(bpy.data.meshes)))
        print("Esc cancelled the import: %s" % module.last_import["message"], flush=True)
        state["step"] = "race_start"
        return 0.1
    if state["step"] == "race_start":
        if state["cycle"] == RACE_CYCLES:
            print("%d more imports, Esc at once or at random moments: %d cancelled, %d finished first"
                  % (RACE_CYCLES, state["ended"]["CANCELLED"], state["ended"]["FINISHED"]), flush=True)
            r = start(SPEC["big"])
            if r != {"RUNNING_MODAL"}:
                fail("modal import returned %s" % r)
            bpy.ops.wm.read_homefile(use_empty=True)  # ends the operator: its cancel()
            if module.last_import.get("status") != "CANCELLED" or "ended" not in module.last_import["message"]:
                fail("an import running while a file loads ended %s" % module.last_import)
            print("an import running while a file loads: %s" % module.last_import["message"], flush=True)
            print("blender modal test: all checks passed", flush=True)
            os._exit(0)
        r = start(SPEC["big"])
        if r != {"RUNNING_MODAL"}:
            fail("modal import returned %s" % r)
        if state["cycle"] % 2 == 0:
            bpy.context.window_manager.windows[0].event_simulate(type='ESC', value='PRESS')
        else:
            state["esc_at"] = now + rng.uniform(0.0, 0.25)
        state["step"] = "race_wait"
        return 0.01
    if state["step"] == "race_wait":
        if "esc_at" in state and now >= state["esc_at"]:
            bpy.context.window_manager.windows[0].event_simulate(type='ESC', value='PRESS')
            del state["esc_at"]
        if not module.last_import:
            return 0.01
        status = module.last_import["status"]
        if status == "FINISHED":
            counts = [(len(o.data.vertices), len(o.data.polygons)) for o in bpy.data.objects]
            state.setdefault("counts", counts)
            if len(counts) != 1 or counts != state["counts"] or not counts[0][1]:
                fail("import %d finished with %s, earlier %s" % (state["cycle"], counts, state["counts"]))
        elif status != "CANCELLED" or len(bpy.data.objects) or len(bpy.data.meshes):
            fail("import %d ended %s with %d objects" % (state["cycle"], module.last_import, len(bpy.data.objects)))
        if state["cycle"] % 2 == 0 and status != "CANCELLED":
            fail("import %d: Esc pressed at once, but it ended %s" % (state["cycle"], module.last_import))
        state["ended"][status] += 1
        for obj in list(bpy.data.objects):
            bpy.data.objects.remove(obj)
        for me in list(bpy.data.meshes):
            bpy.data.meshes.remove(me)
        state.pop("esc_at", None)
        state["cycle"] += 1
        state["step"] = "race_start"
        return 0.01
    return 0.1


bpy.app.timers.register(tick, first_interval=1.0)
