#!/usr/bin/env python3
"""`isomend check` reads what MeshLab and Blender write.

MeshLab (meshlabserver 2020.09, under xvfb-run): isomend's padded DMC mesh of
the MRI sample is loaded and saved again as PLY (binary, int indices,
"VCGLIB generated"), OBJ and STL; `isomend check` must find the same
triangles, no hole, no edge used 3+ times, no misoriented edge.

Blender's importers (3.4: PLY, OBJ, STL) read what isomend writes, here
streamed (--max-memory: the fixed-length PLY header, faces appended from a
scratch file): the vertex and triangle counts isomend reports.

Blender (3.4, background): a UV sphere (quads and triangle fans) exported
with every mesh exporter Blender has (PLY ascii and binary, STL ascii and
binary, OBJ with normals); `isomend check` must find Blender's vertex and
triangle counts after fan-splitting and a closed, consistently oriented
surface (Euler characteristic 2).

usage: test_peers_hosts.py --isomend PATH --samples DIR --work DIR
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
import clitest  # noqa: E402
from clitest import fail  # noqa: E402


def check(exe, work, name, path, triangles, vertices=None):
    p = subprocess.run([exe, "check", path, "--json", "-"], cwd=work, capture_output=True,
                       text=True, timeout=120)
    if p.returncode != 0:
        fail(name, f"exit {p.returncode}: {p.stderr.strip()} {p.stdout[:300]}")
        return
    c = json.loads(p.stdout)["check"]
    if c["triangles"] != triangles:
        fail(name, f"{c['triangles']} triangles, expected {triangles}")
    if vertices is not None and c["vertices"] != vertices:
        fail(name, f"{c['vertices']} vertices, expected {vertices}")
    if c["holes"] or c["nonmanifold_edges"] or c["misoriented_edges"]:
        fail(name, f"defects: {c}")
    return c


def test_meshlab(exe, work, samples):
    src = os.path.join(work, "anat.ply")
    p = subprocess.run([exe, "extract", os.path.join(samples, "anatomical.nrrd"), "--iso", "7000.5",
                        "--pad", "-q", "-o", src, "--json", os.path.join(work, "anat.json")],
                       capture_output=True, text=True)
    if p.returncode != 0:
        fail("meshlab input", p.stderr)
        return
    j = json.load(open(os.path.join(work, "anat.json")))
    for ext in ("ply", "obj", "stl"):
        out = os.path.join(work, f"meshlab.{ext}")
        p = subprocess.run(["xvfb-run", "-a", "meshlabserver", "-i", src, "-o", out, "-m", "vn"],
                           capture_output=True, text=True, timeout=300)
        if p.returncode != 0 or not os.path.exists(out):
            fail(f"meshlab {ext}", f"meshlabserver exit {p.returncode}: {p.stdout[-300:]} {p.stderr[-300:]}")
            continue
        c = check(exe, work, f"meshlab {ext}", out, j["triangles"],
                  j["vertices"])
        if c and c["euler"] != j["check"]["euler"]:
            fail(f"meshlab {ext}", f"Euler {c['euler']} != {j['check']['euler']}")


BLENDER_SCRIPT = r"""
import bpy, json, sys
out = sys.argv[sys.argv.index("--") + 1]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8)
ob = bpy.context.active_object
me = ob.data
tris = sum(len(p.vertices) - 2 for p in me.polygons)
json.dump({"vertices": len(me.vertices), "triangles": tris}, open(out + "/blender.json", "w"))
kw = dict(use_selection=False)
bpy.ops.export_mesh.ply(filepath=out + "/b_ascii.ply", use_ascii=True, use_normals=False,
                        use_uv_coords=False, use_colors=False)
bpy.ops.export_mesh.ply(filepath=out + "/b_bin.ply", use_ascii=False, use_normals=False,
                        use_uv_coords=False, use_colors=False)
bpy.ops.export_mesh.stl(filepath=out + "/b_ascii.stl", ascii=True)
bpy.ops.export_mesh.stl(filepath=out + "/b_bin.stl", ascii=False)
bpy.ops.wm.obj_export(filepath=out + "/b.obj", export_normals=True, export_uv=True,
                      export_materials=False)
"""


def test_blender(exe, work):
    script = os.path.join(work, "export.py")
    with open(script, "w") as f:
        f.write(BLENDER_SCRIPT)
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python", script, "--", work],
                       capture_output=True, text=True, timeout=300)
    info = os.path.join(work, "blender.json")
    if p.returncode != 0 or not os.path.exists(info):
        fail("blender export", f"exit {p.returncode}: {p.stdout[-500:]} {p.stderr[-500:]}")
        return
    b = json.load(open(info))
    for name in ("b_ascii.ply", "b_bin.ply", "b_ascii.stl", "b_bin.stl", "b.obj"):
        c = check(exe, work, f"blender {name}", os.path.join(work, name), b["triangles"], b["vertices"])
        if c and (c["euler"] != 2 or c["components"] != 1):
            fail(f"blender {name}", f"not one closed sphere: {c}")


IMPORT_SCRIPT = r"""
import bpy, json, sys
args = sys.argv[sys.argv.index("--") + 1:]
out, files = args[0], args[1:]
result = {}
for path in files:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if path.endswith(".ply"):
        bpy.ops.import_mesh.ply(filepath=path)
    elif path.endswith(".obj"):
        bpy.ops.wm.obj_import(filepath=path)
    else:
        bpy.ops.import_mesh.stl(filepath=path)
    me = [o for o in bpy.context.scene.objects if o.type == "MESH"][0].data
    result[path] = {"vertices": len(me.vertices),
                    "triangles": sum(len(p.vertices) - 2 for p in me.polygons)}
json.dump(result, open(out, "w"))
"""


def test_blender_imports(exe, work, samples):
    src = os.path.join(samples, "anatomical.nrrd")
    base = [src, "--iso", "7000.5", "--pad", "-q"]
    p = subprocess.run([exe, "extract", *base, "-o", os.path.join(work, "probe.ply"), "--json", "-"],
                       capture_output=True, text=True)
    if p.returncode != 0:
        fail("blender import input", p.stderr)
        return
    j = json.loads(p.stdout)
    limit = str((j["memory_estimate"] + j["memory_streaming"]) // 2)
    files = []
    for name, extra in (("s.ply", []), ("s_nonormals.ply", ["--no-normals"]), ("s.obj", []),
                        ("s.stl", [])):
        path = os.path.join(work, name)
        q = subprocess.run([exe, "extract", *base, *extra, "-o", path, "--max-memory", limit,
                            "--json", "-"], capture_output=True, text=True)
        if q.returncode != 0 or not json.loads(q.stdout)["streamed"]:
            fail(f"blender import {name}", f"isomend extract: {q.stderr}")
            continue
        files.append(path)
    script = os.path.join(work, "import.py")
    with open(script, "w") as f:
        f.write(IMPORT_SCRIPT)
    res = os.path.join(work, "imported.json")
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python", script, "--", res, *files],
                       capture_output=True, text=True, timeout=600)
    if p.returncode != 0 or not os.path.exists(res):
        fail("blender import", f"exit {p.returncode}: {p.stdout[-500:]} {p.stderr[-500:]}")
        return
    got = json.load(open(res))
    for path in files:
        g = got.get(path)
        if not g or g["triangles"] != j["triangles"]:
            fail(f"blender import {os.path.basename(path)}", f"{g} vs {j['triangles']} triangles")
        elif not path.endswith(".stl") and g["vertices"] != j["vertices"]:
            fail(f"blender import {os.path.basename(path)}", f"{g} vs {j['vertices']} vertices")
        elif path.endswith(".stl") and not 0 < g["vertices"] <= j["vertices"]:
            fail(f"blender import {os.path.basename(path)}", f"STL welded to {g['vertices']} vertices")
        else:
            print(f"ok   Blender imports isomend's streamed {os.path.basename(path)}: {g}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--samples", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    if os.path.exists(a.work):
        shutil.rmtree(a.work)
    os.makedirs(a.work)
    for tool in ("meshlabserver", "xvfb-run", "blender"):
        if not shutil.which(tool):
            fail("tools", f"{tool} not found (bash scripts/deps.sh test installs it)")
    if not clitest.failures:
        exe = os.path.abspath(a.isomend)
        test_meshlab(exe, a.work, os.path.abspath(a.samples))
        test_blender(exe, a.work)
        test_blender_imports(exe, a.work, os.path.abspath(a.samples))
    if not clitest.failures:
        shutil.rmtree(a.work)
    return clitest.summary()


if __name__ == "__main__":
    sys.exit(main())
