"""Runs inside headless Blender (see run_blender_tests.py, which prepares cases.json):

    blender -b --factory-startup -noaudio --python-exit-code 1 --python blender_import_test.py -- cases.json

Installs the add-on as a user would (the legacy zip through Preferences >
Add-ons > Install, or the extension zip through Install from Disk in Blender
4.2+: blender_install.py), enables it, and for each case calls bpy.ops.import_mesh.slice_stack, then
asserts: exactly one new object named after the stack; vertex and triangle
counts (and mending triangles) equal to the `isomend extract` command line's
on the same input; mesh.validate() returns False (nothing to repair); every
edge used exactly twice (padded: closed); positive signed volume (outward
winding) and outward custom normals; the spacing and unit scale in the
object's dimensions and the origin in its location; the importer's geometry
warning in the import's outcome (``last_import``) exactly when the CLI gives
one, and for a series whose slices are not evenly spaced the vertices at the
slices' true positions (issue 34).  A label map (issue 36): one object per
label in one new collection, named after its segment, with a material of
its colour and the CLI's per-label counts, closed; a colour table's names;
refusals leave nothing behind.  Broken inputs must make
the operator raise RuntimeError with the reason and leave nothing behind.
Any failed assertion exits non-zero (--python-exit-code 1).
"""
import json
import math
import os
import sys
import time

import bpy
import numpy as np

spec_path = sys.argv[sys.argv.index("--") + 1]
with open(spec_path) as fp:
    SPEC = json.load(fp)

failures = []


def check(cond, message):
    if not cond:
        failures.append(message)
        print("FAIL: " + message, flush=True)


# ------------------------------------------------------------ install + enable
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_install  # noqa: E402

ADDON, module = blender_install.install(SPEC)
# the menu entry exists
assert any(getattr(f, "__name__", "") == "menu_func_import"
           for f in bpy.types.TOPBAR_MT_file_import._dyn_ui_initialize()), "File > Import entry missing"
# the method list starts with the three thesis methods
methods = [item[0] for item in module._method_items(None, bpy.context)]
assert methods[:3] == ["DMC", "MC", "DURST"], methods


def reset():
    bpy.ops.wm.read_homefile(use_empty=True)
    assert hasattr(bpy.types, "IMPORT_MESH_OT_slice_stack"), "read_homefile unregistered the add-on"


def mesh_arrays(me):
    nv, nl, nt = len(me.vertices), len(me.loops), len(me.polygons)
    co = np.empty(3 * nv, np.float32)
    me.vertices.foreach_get("co", co)
    vi = np.empty(nl, np.int32)
    me.loops.foreach_get("vertex_index", vi)
    totals = np.empty(nt, np.int32)
    me.polygons.foreach_get("loop_total", totals)
    return co.reshape(-1, 3), vi, totals


def run_case(i, case):
    reset()
    p = case["params"]
    kwargs = dict(directory=case["directory"], files=[{"name": n} for n in case["files"]],
                  use_suggested_iso=p["use_suggested_iso"], method=p["method"],
                  spacing=p["spacing"], unit_scale=p["unit_scale"], pad=p["pad"], smooth=p["smooth"],
                  gradient_normals=p.get("gradient_normals", True))
    if not p["use_suggested_iso"]:
        kwargs["iso"] = p["iso"]  # an iso that is passed is the level used
    for key in ("series", "grid_axes"):  # DICOM
        if key in p:
            kwargs[key] = p[key]
    t0 = time.perf_counter()
    result = bpy.ops.import_mesh.slice_stack(**kwargs)
    seconds = time.perf_counter() - t0
    tag = "case %d (%s, %s)" % (i, case["name"], p["method"])
    check(result == {"FINISHED"}, "%s: operator returned %s" % (tag, result))
    objs = list(bpy.data.objects)
    check(len(objs) == 1, "%s: expected one object, got %d" % (tag, len(objs)))
    obj = objs[0]
    check(obj.name == case["name"], "%s: object named %r" % (tag, obj.name))
    check(bpy.context.view_layer.objects.active == obj and obj.select_get(), "%s: not active/selected" % tag)
    me = obj.data
    cli = case["cli"]
    co, vi, totals = mesh_arrays(me)
    check(len(me.vertices) == cli["vertices"], "%s: %d vertices, CLI %d" % (tag, len(me.vertices), cli["vertices"]))
    check(len(me.polygons) == cli["triangles"],
          "%s: %d triangles, CLI %d" % (tag, len(me.polygons), cli["triangles"]))
    check(bool((totals == 3).all()), "%s: not all polygons are triangles" % tag)
    check(obj["isomend_mending_triangles"] == cli["triangles_by_origin"]["mend"],
          "%s: %d mending triangles, CLI %d" % (tag, obj["isomend_mending_triangles"],
                                                cli["triangles_by_origin"]["mend"]))
    check(math.isclose(obj["isomend_iso"], cli["iso"], rel_tol=1e-12, abs_tol=1e-9),
          "%s: iso %r, CLI %r" % (tag, obj["isomend_iso"], cli["iso"]))
    # edge usage: padded DMC surfaces are closed 2-manifolds (every edge used
    # exactly twice); MC's holes and Durst's extra polygons show as in the CLI's check
    ei = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("edge_index", ei)
    uses = np.bincount(ei, minlength=len(me.edges))
    once, more = int((uses == 1).sum()), int((uses > 2).sum())
    if p["method"] == "DMC" and p["pad"]:
        check(once == 0, "%s: %d edges used once (holes)" % (tag, once))
        check(more == 0, "%s: %d edges used 3+ times" % (tag, more))
    check(once == cli["check"]["holes"] + cli["check"]["border_edges"],
          "%s: %d edges used once, CLI check %s" % (tag, once, cli["check"]))
    check(more == cli["check"]["nonmanifold_edges"],
          "%s: %d edges used 3+ times, CLI check %s" % (tag, more, cli["check"]))
    if p["method"] == "MC":
        check(once > 0, "%s: MC on this stack should leave holes" % tag)
    check(len(me.edges) == cli["check"]["edges"], "%s: %d edges, CLI %d" % (tag, len(me.edges), cli["check"]["edges"]))
    # signed volume (outward winding); only meaningful for closed surfaces
    tri = co.astype(np.float64)[vi.reshape(-1, 3)]
    signed = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0
    if once == 0:
        check(signed > 0, "%s: signed volume %g is not positive" % (tag, signed))
    # validate() returns True when it had to repair something
    check(me.validate(verbose=True) is False, "%s: mesh.validate() repaired the mesh" % tag)
    check(len(me.vertices) == cli["vertices"] and len(me.polygons) == cli["triangles"],
          "%s: validate() changed the counts" % tag)
    # normals: the custom split normals are the core's gradient normals (Blender
    # stores them compressed), and they point to the faces' side on the whole
    if p["smooth"] and p.get("gradient_normals", True):
        check(me.has_custom_normals, "%s: no custom normals" % tag)
        paths = ([case["directory"]] if not case["files"] else
                 [case["directory"] + "/" + n for n in sorted(case["files"], key=module.import_stack.natural_key)])
        spacing = p["spacing"] if any(p["spacing"]) else None
        core = module.isomend.extract_source(
            paths, iso=None if p["use_suggested_iso"] else p["iso"], method=p["method"].lower(),
            pad=p["pad"], spacing=spacing, series=p.get("series") or None,
            grid_axes=p.get("grid_axes", False))
        ln = np.empty(3 * len(me.loops), np.float32)
        if hasattr(me, "corner_normals"):   # Blender 4.1+: computed on demand
            me.corner_normals.foreach_get("vector", ln)
        else:                               # Blender < 4.1
            me.calc_normals_split()
            me.loops.foreach_get("normal", ln)
        ln = ln.reshape(-1, 3)
        want = core.normals[vi]
        cos = np.einsum("ij,ij->i", ln, want)
        # Blender gives a zero split normal to a vertex whose faces are all nearly
        # degenerate (a surface grazing a sample: a fan with no angle); allow that
        # only there, and rarely.
        zero = np.linalg.norm(ln, axis=1) < 0.5
        area = np.empty(len(me.polygons), np.float32)
        me.polygons.foreach_get("area", area)
        tiny = area[np.arange(len(me.loops)) // 3] < 0.1 * np.median(area)
        check(bool((~zero | tiny).all()) and int(zero.sum()) <= max(8, len(me.loops) // 10000),
              "%s: %d zero split normals (%d not on tiny faces)" % (tag, int(zero.sum()), int((zero & ~tiny).sum())))
        check(float(cos[~zero].min()) > 0.999, "%s: custom normals differ from the core's (min cos %.5f)"
              % (tag, float(cos[~zero].min())))
        pn = np.empty(3 * len(me.polygons), np.float32)
        me.polygons.foreach_get("normal", pn)
        agree = np.einsum("ij,ij->i", ln, np.repeat(pn.reshape(-1, 3), 3, axis=0))
        check(float((agree > 0).mean()) > 0.9,
              "%s: only %.1f%% of the gradient normals agree with the faces" % (tag, 100 * (agree > 0).mean()))
        smooth = np.empty(len(me.polygons), bool)
        me.polygons.foreach_get("use_smooth", smooth)
        check(bool(smooth.all()), "%s: faces not smooth" % tag)
        if hasattr(me, "free_normals_split"):
            me.free_normals_split()
    else:
        check(not me.has_custom_normals, "%s: custom normals without gradient_normals" % tag)
        smooth = np.empty(len(me.polygons), bool)
        me.polygons.foreach_get("use_smooth", smooth)
        check(bool(smooth.all()) if p["smooth"] else not smooth.any(),
              "%s: use_smooth is not %s on every face" % (tag, p["smooth"]))
    # placement: the object sits at the volume's origin (the CLI's), and its world
    # bounding box is the CLI mesh's, both in millimetres times unit scale
    s = p["unit_scale"]
    # a DICOM series in patient axes sits at its first slice's Image Position (Patient)
    dicom = cli.get("dicom")
    place = dicom["position"] if dicom and dicom["axes"] == "patient" else cli["origin"]
    want_loc = [o * s for o in place]
    check(np.allclose(obj.location[:], want_loc, atol=1e-6 + 1e-6 * max(map(abs, want_loc))),
          "%s: location %s, expected the CLI's origin %s x unit scale = %s"
          % (tag, tuple(obj.location), cli["origin"], want_loc))
    world = co.astype(np.float64) + np.array(obj.location[:])
    got_box = np.concatenate([world.min(0), world.max(0)])
    want_box = np.array(case["cli_bbox"]) * s
    check(np.allclose(got_box, want_box, rtol=1e-5, atol=1e-6 * s * np.abs(want_box).max()),
          "%s: world bounding box %s, CLI mesh's %s" % (tag, np.round(got_box, 6), np.round(want_box, 6)))
    spacing = cli["spacing"]
    dims = np.array(obj.dimensions[:])
    # padded surfaces lie within the padded grid box and beyond the sample grid's half-cells
    n = np.array(cli["dims"], float)
    upper = (n + 1) * np.array(spacing) * s
    if cli.get("world_transform") is not None:  # a turned grid: its box is larger
        upper = np.full(3, np.linalg.norm(upper))
    if "slice_z" in case:  # slices where they are: the padded grid ends a gap beyond the ends
        z = np.array(case["slice_z"])
        upper[2] = (z[-1] - z[0] + (z[1] - z[0]) + (z[-1] - z[-2])) * s
    check(bool((dims <= upper * (1 + 1e-5)).all()) and bool((dims > 0).all()),
          "%s: dimensions %s exceed the padded grid %s" % (tag, dims, upper))
    # the importer's warning on the slices' geometry: reported for an uneven
    # series (the CLI's words, with the object's name), nothing otherwise
    warning = cli.get("geometry", {}).get("warning", "")
    want = "%s: %s" % (obj.name, warning) if warning else ""
    check(module.last_import.get("warning") == want,
          "%s: the import's warning %r, expected %r" % (tag, module.last_import.get("warning"), want))
    if "slice_z" in case:
        # issue 34: an uneven series is meshed at its slices' true positions
        z = np.array(case["slice_z"])
        wz = world[:, 2] / s
        check(z[0] - 1e-3 <= wz.min() and wz.max() <= z[-1] + 1e-3,
              "%s: vertices' z %.4f .. %.4f outside the slices' %.4f .. %.4f" % (tag, wz.min(), wz.max(), z[0], z[-1]))
        if case.get("every_slice"):
            # unpadded, a surface in every slice: the z span is the first and
            # last slices', and every slice's true z carries vertices
            check(abs(wz.min() - z[0]) < 1e-3 and abs(wz.max() - z[-1]) < 1e-3,
                  "%s: vertices' z span %.4f .. %.4f, the first and last slices are at %.4f, %.4f"
                  % (tag, wz.min(), wz.max(), z[0], z[-1]))
            zs = np.unique(np.round(wz, 4))
            near = np.abs(zs[:, None] - z[None, :]).min(axis=0)
            check(bool((near < 1e-3).all()), "%s: no vertex at the true z of slices %s"
                  % (tag, np.flatnonzero(near >= 1e-3).tolist()))
    print("%s: %d vertices, %d triangles, %d mending, import %.3f s, dimensions %s"
          % (tag, len(me.vertices), len(me.polygons), obj["isomend_mending_triangles"], seconds,
             np.round(dims, 5)), flush=True)
    return dims


dims_by_case = []
for i, case in enumerate(SPEC["cases"]):
    dims_by_case.append(run_case(i, case))
    ref = case.get("same_as")
    if ref is not None:
        # the same stack at another spacing: dimensions scale axis by axis
        ratio = np.array(case["params"]["spacing"]) / np.array(SPEC["cases"][ref]["params"]["spacing"])
        check(np.allclose(dims_by_case[-1], dims_by_case[ref] * ratio, rtol=1e-5),
              "case %d: dimensions %s are not case %d's %s scaled by %s"
              % (i, dims_by_case[-1], ref, dims_by_case[ref], ratio))

# ------------------------------------------------------------ filepath alone (as a script would)
peanut = [c for c in SPEC["cases"] if c["name"] == "peanut"]
if peanut:
    c = peanut[0]
    reset()
    bpy.ops.import_mesh.slice_stack(filepath=c["directory"] + "/" + c["files"][0], method="DURST",
                                    smooth=False)
    objs = list(bpy.data.objects)
    check(len(objs) == 1 and objs[0].name == "peanut"
          and len(objs[0].data.polygons) == c["cli"]["triangles"],
          "filepath= import: %s" % [(o.name, len(o.data.polygons)) for o in objs])

# ------------------------------------------------------------ an explicit iso is never ignored
# (issue 26 item 5) on a real MRI stack: iso passed alone, as a script user
# would, and together with use_suggested_iso=True; the suggestion otherwise
real = SPEC.get("explicit_iso")
if real:
    calls = [("iso=%g, pad=True" % real["iso"], dict(iso=real["iso"]), real["iso"], real["cli_explicit"]),
             ("iso=%g, use_suggested_iso=True, pad=True" % real["iso"],
              dict(iso=real["iso"], use_suggested_iso=True), real["iso"], real["cli_explicit"]),
             ("pad=True (no iso)", {}, real["suggested"], real["cli_suggested"])]
    for what, kwargs, want_iso, cli in calls:
        reset()
        r = bpy.ops.import_mesh.slice_stack(directory=real["directory"], pad=True, **kwargs)
        objs = list(bpy.data.objects)
        check(r == {"FINISHED"} and len(objs) == 1, "real stack, %s: %s, %d objects" % (what, r, len(objs)))
        if len(objs) == 1:
            obj = objs[0]
            check(obj["isomend_iso"] == want_iso, "real stack, %s: built at iso %r, not %r"
                  % (what, obj["isomend_iso"], want_iso))
            check((len(obj.data.vertices), len(obj.data.polygons)) == (cli["vertices"], cli["triangles"]),
                  "real stack, %s: %d vertices, %d triangles; the CLI at iso %g: %d, %d"
                  % (what, len(obj.data.vertices), len(obj.data.polygons), want_iso, cli["vertices"],
                     cli["triangles"]))
            print("real stack, %s: iso %g, %d triangles (the suggestion is %g)"
                  % (what, obj["isomend_iso"], len(obj.data.polygons), real["suggested"]), flush=True)
    check(real["cli_explicit"]["triangles"] != real["cli_suggested"]["triangles"],
          "the explicit iso must give another surface than the suggestion")

# ------------------------------------------------------------ post-processing (issue 37)
# Minimum Component, Smooth Iterations and Decimate Ratio: the CLI's mesh with
# --min-component 20 --smooth 5 --decimate 0.2 (counts, closed), about a fifth
# of the plain import's triangles, and the report says what each step did
post = SPEC.get("postprocess")
if post:
    reset()
    pp, cli = post["params"], post["cli"]
    r = bpy.ops.import_mesh.slice_stack(directory=post["directory"], **pp)
    objs = list(bpy.data.objects)
    check(r == {"FINISHED"} and len(objs) == 1, "post-processing import: %s, %d objects" % (r, len(objs)))
    if len(objs) == 1:
        me = objs[0].data
        want = cli["check"]  # the counts of the CLI's final mesh
        check((len(me.vertices), len(me.polygons)) == (want["vertices"], want["triangles"]),
              "post-processing: %d vertices, %d triangles; the CLI's %d, %d"
              % (len(me.vertices), len(me.polygons), want["vertices"], want["triangles"]))
        ratio = len(me.polygons) / post["plain_triangles"]
        check(0.17 < ratio < 0.23, "post-processing: %d triangles are %.3f of the plain import's %d"
              % (len(me.polygons), ratio, post["plain_triangles"]))
        ei = np.empty(len(me.loops), np.int32)
        me.loops.foreach_get("edge_index", ei)
        uses = np.bincount(ei, minlength=len(me.edges))
        check(bool((uses == 2).all()), "post-processing: %d edges not used exactly twice (not closed)"
              % int((uses != 2).sum()))
        check(me.validate(verbose=True) is False, "post-processing: mesh.validate() repaired the mesh")
        msg = module.last_import.get("message", "")
        c, d = cli["postprocess"]["clean"], cli["postprocess"]["decimate"]
        for part in ("clean-up: %d of %d components kept" % (c["components_after"], c["components_before"]),
                     "smoothed: %d vertices moved" % cli["postprocess"]["smooth"]["moved_vertices"],
                     "decimated: %d -> %d triangles (target %d reached)"
                     % (d["triangles_before"], d["triangles_after"], d["target_triangles"]),
                     "largest error"):
            check(part in msg, "post-processing: the report %r does not say %r" % (msg, part))
        print("post-processing: %d triangles (%.3f of %d); %s" % (len(me.polygons), ratio,
                                                                  post["plain_triangles"], msg), flush=True)
    # a plain import (the properties' defaults: off) reports no post-processing
    reset()
    bpy.ops.import_mesh.slice_stack(directory=post["directory"], iso=pp["iso"], pad=True,
                                    spacing=pp["spacing"])
    check("decimated" not in module.last_import.get("message", "x decimated"),
          "a plain import reports post-processing: %r" % module.last_import.get("message"))

# ------------------------------------------------------------ label maps (issue 36)
lab = SPEC.get("labels")
if lab:
    def nothing_left():
        return (len(bpy.data.objects), len(bpy.data.meshes), len(bpy.data.materials),
                len(bpy.data.collections)) == (0, 0, 0, 0)

    reset()
    folder, fname = os.path.split(lab["path"])
    r = bpy.ops.import_mesh.slice_stack(directory=folder, files=[{"name": fname}], label_map=True,
                                        pad=True, unit_scale=1.0)
    check(r == {"FINISHED"}, "label map: operator returned %s" % r)
    cols = list(bpy.data.collections)
    check(len(cols) == 1 and cols[0].name == "organs", "label map: one collection 'organs': %s"
          % [c.name for c in cols])
    objs = {o.name: o for o in (cols[0].objects if cols else [])}
    check(sorted(objs) == sorted(name for _, name, _ in lab["segments"]),
          "label map: objects %s" % sorted(objs))
    check(len(bpy.data.objects) == 3, "label map: %d objects in all" % len(bpy.data.objects))
    for value, name, color in lab["segments"]:
        obj = objs.get(name)
        if obj is None:
            continue
        me, cli = obj.data, lab["cli"][str(value)]
        check((len(me.vertices), len(me.polygons)) == (cli["vertices"], cli["triangles"]),
              "label %s: %d vertices, %d triangles; the CLI's %d, %d"
              % (name, len(me.vertices), len(me.polygons), cli["vertices"], cli["triangles"]))
        ei = np.empty(len(me.loops), np.int32)
        me.loops.foreach_get("edge_index", ei)
        uses = np.bincount(ei, minlength=len(me.edges))
        check(bool((uses == 2).all()), "label %s: %d edges not used exactly twice"
              % (name, int((uses != 2).sum())))
        check(me.validate(verbose=True) is False, "label %s: mesh.validate() repaired it" % name)
        check(obj["isomend_label"] == value, "label %s: isomend_label %r" % (name, obj["isomend_label"]))
        mats = list(me.materials)
        want = module.import_stack.srgb_to_linear(tuple(round(255 * c) for c in color))
        check(len(mats) == 1 and mats[0].name == name
              and np.allclose(tuple(mats[0].diffuse_color), want, atol=1e-6),
              "label %s: material %s, want colour %s" % (name, [(m.name, tuple(m.diffuse_color))
                                                          for m in mats], want))
        if value == 1:  # the box of 8 x 14 x 10 voxels, spacing (0.8, 0.8, 1.5), unit_scale 1
            check(np.allclose(tuple(obj.dimensions), (6.4, 11.2, 15.0), atol=1e-4),
                  "label %s: dimensions %s, not 6.4 x 11.2 x 15" % (name, tuple(obj.dimensions)))
    print("label map: %s" % module.last_import.get("message"), flush=True)
    check("names from seg.nrrd" in module.last_import.get("message", ""),
          "label map report: %r" % module.last_import.get("message"))

    # one label, named and coloured by a colour table
    reset()
    r = bpy.ops.import_mesh.slice_stack(directory=folder, files=[{"name": fname}], label_map=True,
                                        labels="2", label_table=lab["table"], pad=True)
    objs = list(bpy.data.objects)
    check(r == {"FINISHED"} and [o.name for o in objs] == ["Right-Kidney"],
          "label 2 with a table: %s %s" % (r, [o.name for o in objs]))
    if objs:
        check(np.allclose(tuple(objs[0].data.materials[0].diffuse_color),
                          module.import_stack.srgb_to_linear((12, 34, 56)), atol=1e-6),
              "label 2: the table's colour")

    # refusals: a RuntimeError naming the reason, nothing left behind
    folder_f, fname_f = os.path.split(lab["fractions"])
    for what, kwargs, expect in (
            ("a label not present", dict(directory=folder, files=[{"name": fname}], labels="1,9"),
             "label 9 is not in"),
            ("a label listed twice", dict(directory=folder, files=[{"name": fname}], labels="2,2"),
             "listed twice"),
            ("a fraction", dict(directory=folder_f, files=[{"name": fname_f}]), "non-integer sample 1.5"),
            ("a missing table", dict(directory=folder, files=[{"name": fname}],
                                     label_table=lab["table"] + ".missing"), "cannot open"),
            ("post-processing", dict(directory=folder, files=[{"name": fname}], smooth_iterations=3),
             "does not apply to a label map")):
        reset()
        try:
            bpy.ops.import_mesh.slice_stack(label_map=True, **kwargs)
            check(False, "label map, %s: no RuntimeError" % what)
        except RuntimeError as exc:
            check(expect in str(exc), "label map, %s: %r does not mention %r" % (what, str(exc), expect))
            print("label map error ok: %s" % str(exc).strip(), flush=True)
        check(nothing_left(), "label map, %s: something was left behind" % what)

# ------------------------------------------------------------ errors leave nothing behind
for err in SPEC["errors"]:
    reset()
    kwargs = dict(directory=err["directory"], files=[{"name": n} for n in err["files"]])
    if "spacing" in err:
        kwargs["spacing"] = err["spacing"]
    if "series" in err:
        kwargs["series"] = err["series"]
    try:
        bpy.ops.import_mesh.slice_stack(**kwargs)
        check(False, "error case %s: no RuntimeError" % err["directory"])
    except RuntimeError as exc:
        for want in err["expect"].split("|"):
            check(want in str(exc), "error case: %r does not mention %r" % (str(exc), want))
        print("error case ok: %s" % str(exc).strip(), flush=True)
    check(len(bpy.data.objects) == 0 and len(bpy.data.meshes) == 0,
          "error case %s left %d objects, %d meshes" % (err["directory"], len(bpy.data.objects),
                                                        len(bpy.data.meshes)))

blender_install.uninstall(ADDON)
check(not hasattr(bpy.types, "IMPORT_MESH_OT_slice_stack"), "unregister left the operator")

if failures:
    raise AssertionError("%d check(s) failed:\n  %s" % (len(failures), "\n  ".join(failures)))
print("blender add-on test: all checks passed", flush=True)
