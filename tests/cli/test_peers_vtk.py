#!/usr/bin/env python3
"""isomend's mesh files against VTK, an independent reader/writer and checker.

1. Meshes written by VTK (PLY ascii, binary little and big endian; STL ascii
   and binary; OBJ) are read by `isomend check`: same vertex and triangle
   counts as VTK's, a closed sphere is continuous (exit 0), an open one is not
   (exit 1), a quad mesh is fan-split.
2. Meshes written by isomend (PLY, OBJ, STL) are read by VTK: same counts,
   PLY normals present and unit length.
3. vtkFeatureEdges (boundary and non-manifold edges, computed by VTK) agrees
   with isomend's continuity report on extracted meshes.

usage: test_peers_vtk.py --isomend PATH --samples DIR --work DIR
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

import vtk
from vtk.util.numpy_support import vtk_to_numpy

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
import clitest  # noqa: E402
from clitest import fail  # noqa: E402


def run(exe, work, *args):
    p = subprocess.run([exe, *args], cwd=work, capture_output=True, text=True, timeout=120)
    return p.returncode, p.stdout, p.stderr


def triangulated(source):
    source.Update()
    tri = vtk.vtkTriangleFilter()
    tri.SetInputConnection(source.GetOutputPort())
    tri.Update()
    clean = vtk.vtkCleanPolyData()
    clean.SetInputConnection(tri.GetOutputPort())
    clean.Update()
    return clean.GetOutput()


def write_vtk(poly, path, kind):
    if kind.startswith("ply"):
        w = vtk.vtkPLYWriter()
        if kind == "ply_ascii":
            w.SetFileTypeToASCII()
        else:
            w.SetFileTypeToBinary()
            if kind == "ply_be":
                w.SetDataByteOrderToBigEndian()
            else:
                w.SetDataByteOrderToLittleEndian()
    elif kind.startswith("stl"):
        w = vtk.vtkSTLWriter()
        if kind == "stl_ascii":
            w.SetFileTypeToASCII()
        else:
            w.SetFileTypeToBinary()
    else:
        w = vtk.vtkOBJWriter()
    w.SetFileName(path)
    w.SetInputData(poly)
    if not w.Write():
        raise RuntimeError(f"VTK could not write {path}")


def read_vtk(path):
    ext = os.path.splitext(path)[1].lower()
    r = {".ply": vtk.vtkPLYReader, ".obj": vtk.vtkOBJReader, ".stl": vtk.vtkSTLReader}[ext]()
    r.SetFileName(path)
    r.Update()
    return r.GetOutput()


def feature_edges(poly):
    """(boundary edges, non-manifold edges) as VTK counts them."""
    out = {}
    for what in ("boundary", "nonmanifold"):
        fe = vtk.vtkFeatureEdges()
        fe.SetInputData(poly)
        fe.SetBoundaryEdges(what == "boundary")
        fe.SetNonManifoldEdges(what == "nonmanifold")
        fe.SetFeatureEdges(False)
        fe.SetManifoldEdges(False)
        fe.Update()
        out[what] = fe.GetOutput().GetNumberOfLines()
    return out["boundary"], out["nonmanifold"]


def test_vtk_written(exe, work):
    sphere = vtk.vtkSphereSource()
    sphere.SetThetaResolution(24)
    sphere.SetPhiResolution(13)
    closed = triangulated(sphere)
    nv, nt = closed.GetNumberOfPoints(), closed.GetNumberOfCells()
    for kind, ext in (("ply_ascii", "ply"), ("ply_le", "ply"), ("ply_be", "ply"),
                      ("stl_ascii", "stl"), ("stl_bin", "stl"), ("obj", "obj")):
        path = os.path.join(work, f"sphere_{kind}.{ext}")
        write_vtk(closed, path, kind)
        rc, out, err = run(exe, work, "check", os.path.basename(path), "--json", "-")
        if rc != 0:
            fail(f"vtk {kind}", f"exit {rc}: {err.strip()} {out[:200]}")
            continue
        c = json.loads(out)["check"]
        if (c["vertices"], c["triangles"]) != (nv, nt):
            fail(f"vtk {kind}", f"isomend read {c['vertices']}/{c['triangles']}, VTK wrote {nv}/{nt}")
        if c["holes"] or c["nonmanifold_edges"] or c["misoriented_edges"] or c["euler"] != 2:
            fail(f"vtk {kind}", f"closed sphere not continuous: {c}")
    # an open hemisphere-like cap: a sphere with a restricted theta range has a hole
    cap = vtk.vtkSphereSource()
    cap.SetThetaResolution(16)
    cap.SetPhiResolution(9)
    cap.SetEndTheta(270)
    open_mesh = triangulated(cap)
    b, n = feature_edges(open_mesh)
    write_vtk(open_mesh, os.path.join(work, "open.ply"), "ply_le")
    # a box much larger than the mesh: every once-used edge is a hole
    rc, out, err = run(exe, work, "check", "open.ply", "--box", "-10,-10,-10,10,10,10", "--json", "-")
    c = json.loads(out)["check"] if out else {}
    if rc != 1 or c.get("holes") != b or c.get("nonmanifold_edges") != n:
        fail("vtk open mesh", f"exit {rc}, isomend {c}, VTK boundary {b} non-manifold {n}")
    # a quad mesh (vtkPlaneSource is not triangulated): polygons are fan-split
    plane = vtk.vtkPlaneSource()
    plane.SetResolution(5, 4)
    plane.Update()
    write_vtk(plane.GetOutput(), os.path.join(work, "quads.ply"), "ply_ascii")
    rc, out, err = run(exe, work, "check", "quads.ply", "--json", "-")
    j = json.loads(out) if out else {}
    if rc != 0 or j.get("polygons_split") != 20 or j["check"]["triangles"] != 40 \
            or j["check"]["border_edges"] != 18:
        fail("vtk quads", f"exit {rc}: {out} {err}")


def test_isomend_written(exe, work, samples):
    anat = os.path.join(samples, "anatomical.nrrd")
    for ext in ("ply", "obj", "stl"):
        name = f"isomend {ext} read by VTK"
        rc, out, err = run(exe, work, "extract", anat, "--iso", "7000.5", "--pad", "--quiet",
                           "-o", f"anat.{ext}", "--json", "anat.json")
        if rc != 0:
            fail(name, err)
            continue
        j = json.load(open(os.path.join(work, "anat.json")))
        poly = read_vtk(os.path.join(work, f"anat.{ext}"))
        if ext != "obj" and poly.GetNumberOfPoints() != j["vertices"]:
            fail(name, f"VTK sees {poly.GetNumberOfPoints()} points, isomend wrote {j['vertices']}")
        if poly.GetNumberOfCells() != j["triangles"]:
            fail(name, f"VTK sees {poly.GetNumberOfCells()} cells, isomend wrote {j['triangles']}")
        if ext == "ply":
            normals = poly.GetPointData().GetNormals()
            if normals is None:
                fail(name, "VTK finds no normals in the PLY")
            else:
                import numpy as np
                lengths = np.linalg.norm(vtk_to_numpy(normals), axis=1)
                if abs(lengths - 1).max() > 1e-4:
                    fail(name, f"normals not unit length: {lengths.min()}..{lengths.max()}")
        # VTK's own edge analysis: a padded DMC surface has no boundary, no non-manifold edge
        clean = vtk.vtkCleanPolyData()
        clean.SetInputData(poly)
        clean.Update()
        b, n = feature_edges(clean.GetOutput())
        if b or n or j["check"]["holes"] or j["check"]["nonmanifold_edges"]:
            fail(name, f"VTK boundary {b}, non-manifold {n}; isomend {j['check']}")
    # F1 with plain MC: VTK's boundary edges = isomend's hole edges + border edges
    rc, out, err = run(exe, work, "extract", "builtin:f1", "--iso", "0", "--method", "mc", "-q",
                       "-o", "f1mc.ply", "--json", "f1mc.json")
    j = json.load(open(os.path.join(work, "f1mc.json")))
    b, n = feature_edges(read_vtk(os.path.join(work, "f1mc.ply")))
    if b != j["check"]["holes"] + j["check"]["border_edges"] or n != j["check"]["nonmanifold_edges"]:
        fail("F1 mc edges", f"VTK boundary {b} non-manifold {n}; isomend {j['check']}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--samples", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    if os.path.exists(a.work):
        shutil.rmtree(a.work)
    os.makedirs(a.work)
    exe = os.path.abspath(a.isomend)
    test_vtk_written(exe, a.work)
    test_isomend_written(exe, a.work, os.path.abspath(a.samples))
    if not clitest.failures:
        shutil.rmtree(a.work)
    return clitest.summary()


if __name__ == "__main__":
    sys.exit(main())
