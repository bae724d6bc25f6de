#!/usr/bin/env python3
"""`isomend extract`'s post-processing (--min-component, --largest, --smooth,
--decimate, --target-triangles, --max-error) against independent checks.

Volumes: the bundled MRI (suggested iso), a CT-like phantom in HU (hollow
bone balls, a bone torus, small fragments in soft tissue, noise; i16 raw),
padded random noise (hundreds of components, handles), the thesis's F1 and F2
(builtin:), all with --pad, and two open surfaces (the MRI without --pad: a
border; the MRI with --method mc: holes) whose border and holes must stay as
they are.  For each, every option alone and in combinations:

- the output is a closed oriented 2-manifold (or keeps the input's border and
  holes) by the project's checker (the --json "check" and `isomend check
  FILE`) and by independent ones: vtkFeatureEdges on vtkPLYReader's output
  (not cleaned: cleaning merges points) counts no boundary (or the input's)
  and no non-manifold edge; in numpy every directed edge appears once and its
  reverse once (orientation); components by vtkPolyDataConnectivityFilter,
  and the per-component Euler characteristics (V - E + F, numpy) equal the
  input's, less the components clean-up dropped (recomputed here from the
  input's components: fewer than N triangles, then the K largest);
- decimation: the distance from the decimation's input vertices to the result
  (vtkCellLocator.FindClosestPoint) is at most the reported max_error (1e-4
  relative slack for float32 files), its mean is the reported mean_error, and
  with --max-error E the measured max is at most E; the counts and the
  reached flag agree with the target;
- smoothing: the triangles are the input's, locked (border) vertices do not
  move, the reported volume change is under 0.5 % and vtkMassProperties on
  the input and output agrees with the reported volumes (1e-3 relative);
- the smoothing is VTK's windowed sinc filter: on a closed blob (every vertex
  free, one component) --smooth N for N = 5 and 20 puts every vertex where
  vtkWindowedSincPolyDataFilter (N iterations, pass band 0.1, normalised
  coordinates) puts it, once VTK's own shrink (its coefficients sum to about
  0.998: a best-fit scale about the centre) and isomend's volume restoration
  (a best-fit offset along the normals) are taken out: to 10 % of VTK's mean
  displacement on average (4 % measured: VTK stops its search for the
  filter's offset at 1e-3) and 15 % of its largest at most; --smooth N against
  VTK at 2N iterations must not match (the comparison can fail);
- the same bytes with --threads 1 and --threads 2, confined to one core (the
  post-processing's threads follow the process's cores), and the same bytes twice;
- bad values (--decimate 0, 1.5, x, --max-error -1, --smooth 0, 20000,
  --min-component 0, ...) are usage errors (exit 2) with one line naming the
  flag and no output file; `mpirun -n N isomend-mpi extract` with --decimate
  R, --target-triangles N, --max-error E and --decimate R --max-error E
  writes the bytes of `isomend extract --stream` with the same flags for
  N = 1, 2, 3, closed, the report's counts and target those of the streamed
  run (the streamed targets themselves: test_postprocess_stream.py).

The independent checkers are first run on deliberately broken meshes (a
removed triangle, a flipped one, a triangle used three times, a moved
vertex, a dropped component) to show that each of them can fail.

usage: test_postprocess.py --isomend PATH --samples DIR --work DIR
                           [--isomend-mpi PATH --mpirun PATH]
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import vtk
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import clitest  # noqa: E402
from clitest import fail  # noqa: E402
from vtkcheck import components, distances, feature_edges, read_poly  # noqa: E402


def run(exe, args, cwd, env=None, timeout=600):
    p = subprocess.run([exe, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                       stdin=subprocess.DEVNULL, env=env)
    return p.returncode, p.stdout, p.stderr


# ------------------------------------------------------------------ volumes

def ct_phantom(path, n=72, seed=11):
    """A CT-like i16 volume in HU: air (-1000) around an ellipsoidal body of
    soft tissue (40), three hollow bone balls (cortex 900 around marrow 150),
    a bone torus (genus 1), a dozen small fragments (some only a few
    triangles) and +-40 HU of noise; meshed at 300 HU."""
    rng = np.random.default_rng(seed)
    z, y, x = np.mgrid[0:n, 0:n, 0:n].astype(np.float32)
    c = (n - 1) / 2
    v = np.full((n, n, n), -1000, np.float32)
    body = ((x - c) / (0.46 * n)) ** 2 + ((y - c) / (0.40 * n)) ** 2 + ((z - c) / (0.46 * n)) ** 2 < 1
    v[body] = 40
    for bx, by, bz, r in ((0.32, 0.40, 0.35, 0.13), (0.66, 0.55, 0.40, 0.11), (0.45, 0.62, 0.68, 0.10)):
        d = np.sqrt((x - bx * n) ** 2 + (y - by * n) ** 2 + (z - bz * n) ** 2)
        v[d < r * n] = 900
        v[d < 0.6 * r * n] = 150
    # a torus around the z axis through (0.5, 0.32, 0.7)
    tx, ty, tz, R, rr = 0.52 * n, 0.30 * n, 0.72 * n, 0.09 * n, 0.035 * n
    q = np.sqrt((x - tx) ** 2 + (y - ty) ** 2) - R
    v[q ** 2 + (z - tz) ** 2 < rr * rr] = 1100
    for _ in range(12):
        fx, fy, fz = rng.uniform(0.25, 0.75, 3) * n
        r = rng.uniform(0.9, 2.6)
        v[(x - fx) ** 2 + (y - fy) ** 2 + (z - fz) ** 2 < r * r] = 700
    v += rng.uniform(-40, 40, v.shape).astype(np.float32)
    v.astype("<i2").tofile(path)
    return n


def noise(path, n=18, seed=5):
    np.random.default_rng(seed).integers(0, 256, (n, n, n), dtype=np.uint8).tofile(path)
    return n


# ------------------------------------------------------------------ independent checks

def vtk_volume(poly):
    mp = vtk.vtkMassProperties()
    mp.SetInputData(poly)
    mp.Update()
    return mp.GetVolume()


def edge_stats(faces):
    """Numpy, from the triangles alone: (edges, edges used once, edges used 3+
    times, edges used twice the same way, directed edges used more than once)."""
    d = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]).astype(np.int64)
    und = np.sort(d, axis=1)
    key = und[:, 0] * (1 << 32) + und[:, 1]
    uk, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    # orientation: +1 for a -> b with a < b, -1 otherwise; an edge used twice
    # consistently sums to 0
    sign = np.where(d[:, 0] < d[:, 1], 1, -1)
    ssum = np.bincount(inv, weights=sign, minlength=len(uk))
    dkey = d[:, 0] * (1 << 32) + d[:, 1]
    _, dcnt = np.unique(dkey, return_counts=True)
    return dict(edges=len(uk), once=int((cnt == 1).sum()), many=int((cnt > 2).sum()),
                same_way=int(((cnt == 2) & (ssum != 0)).sum()), directed_dup=int((dcnt > 1).sum()))


def component_eulers(faces):
    """Per component (through shared vertices), in the order of their first
    triangle: (triangles, Euler characteristic V - E + F)."""
    f = faces.astype(np.int64)
    used = np.unique(f)
    remap = np.full(int(f.max()) + 1, -1, np.int64)
    remap[used] = np.arange(len(used))
    g = remap[f]
    nv = len(used)
    rows = np.concatenate([g[:, 0], g[:, 1]])
    cols = np.concatenate([g[:, 1], g[:, 2]])
    m = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(nv, nv))
    ncomp, label = connected_components(m, directed=False)
    tlabel = label[g[:, 0]]
    # order components by their first triangle
    first = np.full(ncomp, len(g), np.int64)
    np.minimum.at(first, tlabel, np.arange(len(g)))
    order = np.argsort(first, kind="stable")
    rank = np.empty(ncomp, np.int64)
    rank[order] = np.arange(ncomp)
    tl = rank[tlabel]
    F = np.bincount(tl, minlength=ncomp)
    V = np.bincount(rank[label], minlength=ncomp)
    d = np.concatenate([g[:, [0, 1]], g[:, [1, 2]], g[:, [2, 0]]])
    und = np.sort(d, axis=1)
    key, idx = np.unique(und[:, 0] * (1 << 32) + und[:, 1], return_index=True)
    E = np.bincount(np.concatenate([tl, tl, tl])[idx], minlength=ncomp)
    return [(int(F[i]), int(V[i] - E[i] + F[i])) for i in range(ncomp)]


def expected_after_clean(comps, min_component, largest):
    kept = [(i, t, e) for i, (t, e) in enumerate(comps) if not min_component or t >= min_component]
    if largest:
        kept = sorted(sorted(kept, key=lambda k: (-k[1], k[0]))[:largest])
    return [(t, e) for _, t, e in kept]


def independent(name, path, want_border=0, want_comps=None):
    """The VTK/numpy verdict on a file; returns (vertices, faces, poly, comps)."""
    verts, faces = clitest.read_ply_arrays(path)
    poly = read_poly(path)
    if poly.GetNumberOfCells() != len(faces) or poly.GetNumberOfPoints() != len(verts):
        fail(name, f"VTK read {poly.GetNumberOfPoints()}/{poly.GetNumberOfCells()}, "
                   f"the PLY has {len(verts)}/{len(faces)}")
    boundary, nonmanifold = feature_edges(poly)
    if boundary != want_border or nonmanifold:
        fail(name, f"vtkFeatureEdges: {boundary} boundary (want {want_border}), "
                   f"{nonmanifold} non-manifold edges")
    es = edge_stats(faces)
    if es["once"] != want_border or es["many"] or es["same_way"] or es["directed_dup"]:
        fail(name, f"edges (numpy): {es}, want {want_border} used once")
    comps = component_eulers(faces)
    nvtk = components(poly)
    if nvtk != len(comps):
        fail(name, f"vtkPolyDataConnectivityFilter: {nvtk} regions, numpy {len(comps)}")
    if want_comps is not None:
        got = sorted(e for _, e in comps)
        want = sorted(e for _, e in want_comps)
        if got != want:
            fail(name, f"per-component Euler {got[:12]}... ({len(got)}, sum {sum(got)}) != the "
                       f"input's {want[:12]}... ({len(want)}, sum {sum(want)})")
    if len(np.unique(faces)) != len(verts):
        fail(name, f"{len(verts) - len(np.unique(faces))} unreferenced vertices")
    return verts, faces, poly, comps


def self_test_checkers():
    """Each independent check fails on a mesh broken on purpose."""
    src = vtk.vtkSphereSource()
    src.SetThetaResolution(16)
    src.SetPhiResolution(9)
    src.Update()
    poly = src.GetOutput()
    pts = vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float32)
    faces = vtk_to_numpy(poly.GetPolys().GetData()).reshape(-1, 4)[:, 1:].astype(np.uint32)

    def es(f):
        return edge_stats(f)
    good = es(faces)
    if good["once"] or good["many"] or good["same_way"] or good["directed_dup"]:
        fail("self-test", f"a closed sphere is not closed: {good}")
    if es(faces[1:])["once"] != 3:
        fail("self-test", "a removed triangle is not seen as 3 once-used edges")
    flipped = faces.copy()
    flipped[5] = flipped[5][::-1]
    if es(flipped)["same_way"] != 3:
        fail("self-test", "a flipped triangle is not seen as 3 edges used twice the same way")
    if es(np.concatenate([faces, faces[:1]]))["many"] != 3:
        fail("self-test", "a triangle used twice is not seen as 3 edges used 3 times")
    comps = component_eulers(faces)
    if comps != [(len(faces), 2)]:
        fail("self-test", f"a sphere's components {comps}")
    two = np.concatenate([faces, faces + len(pts)])
    if component_eulers(two) != [(len(faces), 2)] * 2:
        fail("self-test", "two spheres are not two components of Euler 2")
    if expected_after_clean([(50, 2), (10, 2), (80, 0), (50, 2)], 20, 2) != [(50, 2), (80, 0)]:
        fail("self-test", "expected_after_clean keeps the wrong components")
    # boundary edges by VTK: a sphere less a triangle
    cut = vtk.vtkPolyData()
    cut.SetPoints(poly.GetPoints())
    cells = vtk.vtkCellArray()
    for t in faces[1:]:
        cells.InsertNextCell(3, [int(i) for i in t])
    cut.SetPolys(cells)
    if feature_edges(cut) != (3, 0) or feature_edges(poly) != (0, 0):
        fail("self-test", "vtkFeatureEdges does not see a removed triangle")
    # distances: a vertex moved by 0.25 away from a sphere of radius 0.5
    moved = vtk.vtkPolyData()
    moved.DeepCopy(poly)
    p = np.array(moved.GetPoint(3))
    moved.GetPoints().SetPoint(3, *(p * 1.5))
    d = distances(moved, poly)
    if not (0.2 < d.max() < 0.26) or distances(poly, poly).max() > 1e-6:
        fail("self-test", f"vtkCellLocator distances wrong: {d.max()}")


# ------------------------------------------------------------------ the runs

class Case:
    def __init__(self, name, source_args, border=False):
        self.name = name
        self.args = source_args
        self.border = border  # an open surface: border/holes kept, not closed


def check_json(name, j, want_border, want_holes, max_nm_vertices):
    """The --json check: no non-manifold or misoriented edge, no degenerate
    triangle, the border and holes wanted, at most the input's non-manifold
    vertices (MC's pinches: locked, kept)."""
    c = j["check"]
    if c["nonmanifold_edges"] or c["misoriented_edges"] or c["nonmanifold_vertices"] > max_nm_vertices or \
            c["degenerate_triangles"] or c["border_edges"] != want_border or c["holes"] != want_holes:
        fail(name, f"--json check: {c} (want {want_border} border edges, {want_holes} hole edges, "
                   f"<= {max_nm_vertices} non-manifold vertices)")
    return c


def check_file(exe, work, name, path, c):
    """`isomend check FILE` agrees with the --json check of the run that wrote
    it (a file knows no grid box: border edges may count as holes there)."""
    rc, out, err = run(exe, ["check", path, "--json", "-"], work)
    try:
        fc = json.loads(out)["check"]
    except (ValueError, KeyError) as e:
        fail(name, f"isomend check exit {rc}, --json: {e} {err.strip()}")
        return
    open_edges = c["holes"] + c["border_edges"]
    if fc["holes"] + fc["border_edges"] != open_edges or \
            any(fc[k] != c[k] for k in ("nonmanifold_edges", "misoriented_edges", "components", "euler",
                                        "triangles", "vertices")):
        fail(name, f"isomend check FILE {fc} != --json check {c}")
    if rc != (1 if fc["holes"] else 0) or (not open_edges and rc):
        fail(name, f"isomend check exit {rc} for {fc}")


def test_case(exe, work, case, configs):
    base_path = os.path.join(work, f"{case.name}_base.ply")
    rc, out, err = run(exe, ["extract", *case.args, "-q", "-o", base_path, "--json", "-"], work)
    if rc:
        fail(case.name, f"extract exit {rc}: {err.strip()}")
        return
    base = json.loads(out)
    bc = base["check"]
    want_border = bc["border_edges"] + bc["holes"]
    if case.border != (want_border > 0):
        fail(case.name, f"the input has {want_border} once-used edges")
    bv, bf, bpoly, bcomps = independent(f"{case.name} input", base_path, want_border)
    if (len(bcomps) != bc["components"] and not bc["nonmanifold_vertices"]) or \
            sum(e for _, e in bcomps) != bc["euler"]:
        fail(case.name, f"input: numpy {len(bcomps)} components, Euler {sum(e for _, e in bcomps)}; "
                        f"isomend {bc['components']}, {bc['euler']}")
    ntri = base["triangles"]
    bbox = np.ptp(bv[:, :3], axis=0)
    diag = float(np.linalg.norm(bbox))
    spacing = min(base["spacing"])
    print(f"{case.name}: {ntri} triangles, {bc['components']} components, Euler {bc['euler']}, "
          f"{want_border} once-used edges", flush=True)
    inputs = {(): (base_path, bpoly, bcomps, bv, bf)}  # pre-decimation meshes by the flags before

    def pre_flags(flags):
        """The flags that make the decimation's input (clean-up, smoothing)."""
        out_, i = [], 0
        while i < len(flags):
            if flags[i] in ("--min-component", "--largest", "--smooth"):
                out_ += flags[i:i + 2]
            i += 2
        return tuple(out_)

    for cfg in configs:
        flags = [str(x).format(T=max(4, ntri // 5), E=0.5 * spacing) for x in cfg]
        tag = f"{case.name} {' '.join(flags)}"
        outs = {}
        # "1 core": the process confined to one core (its affinity), so that
        # the post-processing's own threads (one a core) are one as well
        for t in ("1", "2", "2 again", "1 core"):
            path = os.path.join(work, f"{case.name}_{abs(hash((tuple(flags), t))) % 10**8}.ply")
            args = ["extract", *case.args, *flags, "-q", "--threads", t.split()[0], "-o", path,
                    "--json", "-"]
            if t == "1 core":
                one = min(os.sched_getaffinity(0))
                p = subprocess.run([exe, *args], cwd=work, capture_output=True, text=True,
                                   timeout=600, preexec_fn=lambda: os.sched_setaffinity(0, {one}))
                rc, out, err = p.returncode, p.stdout, p.stderr
            else:
                rc, out, err = run(exe, args, work)
            if rc:
                fail(tag, f"exit {rc}: {err.strip()}")
                break
            outs[t] = (path, json.loads(out))
        if len(outs) != 4:
            continue
        path, j = outs["1"]
        if not clitest.same_file(path, outs["2"][0]):
            fail(tag, "--threads 1 and --threads 2 write different files")
        if not clitest.same_file(outs["2"][0], outs["2 again"][0]):
            fail(tag, "two runs write different files")
        if not clitest.same_file(path, outs["1 core"][0]):
            fail(tag, "a run confined to one core writes a different file")
        for t in ("2", "2 again", "1 core"):
            os.remove(outs[t][0])
        pp = j["postprocess"]
        # the expected components: the input's, less what clean-up drops
        mc = int(flags[flags.index("--min-component") + 1]) if "--min-component" in flags else 0
        lg = int(flags[flags.index("--largest") + 1]) if "--largest" in flags else 0
        want_comps = expected_after_clean(bcomps, mc, lg) if (mc or lg) else bcomps
        # once-used edges of the kept components (clean-up may drop some with a border)
        cleaned = bool(mc or lg)
        c = check_json(tag, j, j["check"]["border_edges"] if cleaned else bc["border_edges"],
                       j["check"]["holes"] if cleaned else bc["holes"], bc["nonmanifold_vertices"])
        if not cleaned and c["nonmanifold_vertices"] != bc["nonmanifold_vertices"]:
            fail(tag, f"{c['nonmanifold_vertices']} non-manifold vertices, the input has "
                      f"{bc['nonmanifold_vertices']}")
        kept_border = c["border_edges"] + c["holes"]
        if (mc or lg) and not case.border and kept_border:
            fail(tag, f"{kept_border} once-used edges after clean-up of a closed surface")
        # the checker's components go through edges, clean-up's (and VTK's)
        # through vertices: the same where no vertex is non-manifold
        comps_ok = c["components"] == bc["components"] if not cleaned else \
            bool(bc["nonmanifold_vertices"]) or c["components"] == len(want_comps)
        if not comps_ok or c["euler"] != sum(e for _, e in want_comps):
            fail(tag, f"--json check: {c['components']} components, Euler {c['euler']}; want "
                      f"{len(want_comps)} ({bc['components']} before), {sum(e for _, e in want_comps)}")
        check_file(exe, work, tag, path, c)
        ov, of, opoly, ocomps = independent(tag, path, kept_border, want_comps)
        if mc or lg:
            cl = pp["clean"]
            dropped = sum(t for t, _ in bcomps) - sum(t for t, _ in want_comps)
            if (cl["components_before"], cl["components_after"], cl["triangles_removed"]) != \
                    (len(bcomps), len(want_comps), dropped):
                fail(tag, f"clean report {cl}, want {len(bcomps)} -> {len(want_comps)}, {dropped} "
                          f"triangles removed")
        pre = pre_flags(flags)
        if pre and pre not in inputs:
            # the decimation's input: the same run without the decimation's flags
            ppath = os.path.join(work, f"{case.name}_pre{abs(hash(pre)) % 10**8}.ply")
            rc, out, err = run(exe, ["extract", *case.args, *pre, "-q", "-o", ppath, "--json", "-"], work)
            if rc:
                fail(tag, f"pre-decimation run exit {rc}: {err.strip()}")
                continue
            pv, pf = clitest.read_ply_arrays(ppath)
            inputs[pre] = (ppath, read_poly(ppath), None, pv, pf)
        decimated = pp["decimate"] is not None
        if "--smooth" in flags:
            sm = pp["smooth"]
            v0, v1 = sm["volume_before"], sm["volume_after"]
            # smoothing's input: the clean-up's output; its output: `pre`'s
            cl_flags = tuple(x for i, x in enumerate(pre) if pre[i - (i % 2)] != "--smooth")
            if cl_flags not in inputs:
                cpath = os.path.join(work, f"{case.name}_cl{abs(hash(cl_flags)) % 10**8}.ply")
                run(exe, ["extract", *case.args, *cl_flags, "-q", "-o", cpath], work)
                cv, cf = clitest.read_ply_arrays(cpath)
                inputs[cl_flags] = (cpath, read_poly(cpath), None, cv, cf)
            ipath, ipoly, _, iv, ifc = inputs[cl_flags]
            spath = inputs[pre][0] if decimated else path
            sv, sf = clitest.read_ply_arrays(spath)
            if not np.array_equal(ifc, sf):
                fail(tag, "smoothing changed the triangles")
            lockv = np.unique(locked_vertices(ifc))
            if len(lockv) and not np.array_equal(iv[lockv, :3], sv[lockv, :3]):
                fail(tag, "smoothing moved a border vertex")
            if sm["moved_vertices"] != len(iv) - len(lockv):
                fail(tag, f"moved_vertices {sm['moved_vertices']}, {len(iv)} vertices, {len(lockv)} locked")
            if not case.border:
                if abs(v1 - v0) > 0.005 * abs(v0):
                    fail(tag, f"volume {v0} -> {v1}: {100 * (v1 - v0) / v0:+.3f} %")
                m0, m1 = vtk_volume(ipoly), vtk_volume(read_poly(spath))
                if abs(abs(m0) - abs(v0)) > 1e-3 * abs(v0) or abs(abs(m1) - abs(v1)) > 1e-3 * abs(v1):
                    fail(tag, f"vtkMassProperties {m0} -> {m1}, reported {v0} -> {v1}")
            print(f"  {' '.join(flags):55s} volume {v0:.6g} -> {v1:.6g} ({100 * (v1 - v0) / v0:+.4f} %), "
                  f"moved at most {sm['max_displacement']:.4g}", flush=True)
        d = pp["decimate"]
        if d is None:
            continue
        ipath, ipoly, _, iv, ifc = inputs[pre]
        if (d["triangles_before"], d["triangles_after"], d["vertices_after"]) != (len(ifc), len(of), len(ov)):
            fail(tag, f"decimate report {d}, input {len(ifc)} triangles, output {len(ov)}/{len(of)}")
        ratio = float(flags[flags.index("--decimate") + 1]) if "--decimate" in flags else 0
        target = int(flags[flags.index("--target-triangles") + 1]) if "--target-triangles" in flags else 0
        want_target = max(ratio * len(ifc), target)
        if want_target and abs(d["target_triangles"] - want_target) > 1:
            fail(tag, f"target {d['target_triangles']}, want {want_target}")
        if want_target and d["reached"] != (len(of) <= d["target_triangles"]):
            fail(tag, f"reached {d['reached']} with {len(of)} triangles for {d['target_triangles']}")
        if not want_target and len(of) >= len(ifc) and d["collapses"]:
            fail(tag, f"{d['collapses']} collapses, {len(of)} triangles of {len(ifc)}")
        dist = distances(ipoly, opoly)
        slack = 1e-4 * max(d["max_error"], spacing) + 1e-6 * diag
        if dist.max() > d["max_error"] + slack:
            fail(tag, f"measured max distance {dist.max():.9g} > reported max_error {d['max_error']:.9g} "
                      f"(repro: isomend extract {' '.join(case.args + flags)} -o m.ply)")
        if abs(dist.mean() - d["mean_error"]) > 1e-3 * d["mean_error"] + 1e-6 * diag:
            fail(tag, f"measured mean distance {dist.mean():.9g} != reported mean_error {d['mean_error']:.9g}")
        if dist.max() < d["max_error"] - slack:
            fail(tag, f"reported max_error {d['max_error']:.9g} above the measured {dist.max():.9g}")
        if "--max-error" in flags:
            E = float(flags[flags.index("--max-error") + 1])
            if dist.max() > E * (1 + 1e-4) + 1e-6 * diag:
                fail(tag, f"measured max distance {dist.max():.9g} > --max-error {E}")
        print(f"  {' '.join(flags):55s} {len(of):7d} tri, {len(ocomps):4d} comp, "
              f"max {dist.max():.4g} (rep {d['max_error']:.4g}), mean {dist.mean():.4g}, "
              f"reached {d['reached']}", flush=True)


def locked_vertices(faces):
    """Vertices on once-used edges."""
    d = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]).astype(np.int64)
    und = np.sort(d, axis=1)
    uk, cnt = np.unique(und[:, 0] * (1 << 32) + und[:, 1], return_counts=True)
    once = uk[cnt == 1]
    return np.concatenate([once >> 32, once & 0xffffffff])


CONFIGS = [
    ["--decimate", "0.1"],
    ["--decimate", "0.3"],
    ["--target-triangles", "{T}"],
    ["--max-error", "{E}"],
    ["--smooth", "10"],
    ["--min-component", "20"],
    ["--largest", "1"],
    ["--decimate", "0.1", "--max-error", "{E}"],
    ["--min-component", "20", "--smooth", "10", "--decimate", "0.1"],
    ["--largest", "1", "--decimate", "0.3", "--max-error", "{E}"],
    ["--smooth", "10", "--target-triangles", "{T}"],
    ["--decimate", "0.3", "--target-triangles", "{T}"],
]


def test_errors(exe, mpi, mpirun, work, samples):
    anat = os.path.join(samples, "anatomical.nrrd")
    out = os.path.join(work, "bad.ply")
    bad = [(["--decimate", "0"], "--decimate"), (["--decimate", "1.5"], "--decimate"),
           (["--decimate", "x"], "--decimate"), (["--decimate", "-0.1"], "--decimate"),
           (["--decimate", "nan"], "--decimate"),
           (["--max-error", "-1"], "--max-error"), (["--max-error", "0"], "--max-error"),
           (["--max-error", "inf"], "--max-error"), (["--max-error", "nan"], "--max-error"),
           (["--smooth", "0"], "--smooth"), (["--smooth", "20000"], "--smooth"),
           (["--smooth", "2.5"], "--smooth"), (["--min-component", "0"], "--min-component"),
           (["--min-component", "-3"], "--min-component"), (["--largest", "0"], "--largest"),
           (["--target-triangles", "0"], "--target-triangles"),
           (["--target-triangles", "many"], "--target-triangles"), (["--decimate"], "--decimate")]
    for flags, flag in bad:
        rc, o, err = run(exe, ["extract", anat, "--pad", "-o", out, *flags], work)
        lines = err.strip().splitlines()
        if rc != 2 or len(lines) != 1 or flag not in lines[0] or os.path.exists(out):
            fail(f"bad {' '.join(flags)}", f"exit {rc}, stderr {err.strip()!r}, file {os.path.exists(out)}")
    if mpi:  # isomend-mpi's bad values: usage errors as isomend's
        env = clitest.mpi_env()
        for flags in (["--max-error", "-1"], ["--target-triangles", "0"]):
            p = subprocess.run([mpirun, "-n", "1", mpi, "extract", anat, "--pad", "-o", out, *flags],
                               cwd=work, capture_output=True, text=True, env=env, timeout=120)
            if p.returncode != 2 or flags[0] not in p.stderr or os.path.exists(out):
                fail(f"isomend-mpi {' '.join(flags)}", f"exit {p.returncode}, stderr {p.stderr.strip()!r}")
    # --max-memory forcing the streamed path
    rc, o, err = run(exe, ["extract", anat, "--pad", "-q", "-o", out, "--json", "-"], work)
    j = json.loads(o)
    os.remove(out)
    limit = str((j["memory_estimate"] + j["memory_streaming"]) // 2)
    rc, o, err = run(exe, ["extract", anat, "--pad", "-q", "-o", out, "--max-memory", limit], work)
    if rc or not os.path.exists(out):
        fail("--max-memory alone", f"the streamed run failed: exit {rc}, {err.strip()}")
    if os.path.exists(out):
        os.remove(out)
    # (the streamed steps, --target-triangles and --max-error included, are
    # test_postprocess_stream*.py's)


MPI_STEPS = (["--decimate", "0.1"], ["--target-triangles", "1500"], ["--max-error", "0.8"],
             ["--decimate", "0.2", "--max-error", "0.4"])


def mpi_decimate(exe, mpi, mpirun, work, cases):
    """mpirun -n N isomend-mpi extract with the decimation's flags (MPI_STEPS):
    the bytes of isomend extract --stream with them, for N = 1, 2, 3, chunks
    of 3 layers and the default (--decimate; the others with chunks of 3, not
    on the phantom);
    its JSON check closed and equal to the streamed run's, and its report's
    counts and target."""
    env = clitest.mpi_env()
    for case, steps, chunk in [(c, st, ch) for c in cases for st in MPI_STEPS
                               for ch in (["--chunk-layers", "3"], [])
                               if st == MPI_STEPS[0] or (ch and c.name != "ct")]:
        ref = os.path.join(work, f"{case.name}_dec_stream.ply")
        rc, o, err = run(exe, ["extract", *case.args, *steps, "--stream", *chunk,
                               "-q", "-o", ref, "--json", "-"], work)
        if rc:
            fail(f"{case.name} streamed {' '.join(steps)}", err.strip())
            continue
        jref = json.loads(o)
        for n in (1, 2, 3):
            out = os.path.join(work, f"{case.name}_dec_mpi{n}.ply")
            p = subprocess.run([mpirun, "--oversubscribe", "-n", str(n), mpi, "extract",
                                *case.args, *steps, *chunk, "-q", "-o", out,
                                "--json", "-"], cwd=work, capture_output=True, text=True,
                               env=env, timeout=300)
            what = f"{case.name} isomend-mpi -n {n} {' '.join(steps + chunk)}"
            if p.returncode:
                fail(what, f"exit {p.returncode}: {p.stderr.strip()}")
                continue
            j = json.loads(p.stdout)
            with open(ref, "rb") as f1, open(out, "rb") as f2:
                same = f1.read() == f2.read()
            if not same:
                fail(what, f"not the bytes of isomend extract --stream {' '.join(steps)}")
            elif j["check"] != jref["check"] or not (case.border or j["check"]["continuous"]):
                fail(what, f"check {j['check']} vs {jref['check']}")
            elif any(j["postprocess"]["decimate"][k] != jref["postprocess"]["decimate"][k]
                     for k in ("triangles_before", "triangles_after", "target_triangles",
                               "reached", "max_error")):
                fail(what, f"another report: {j['postprocess']['decimate']} vs the streamed "
                           f"{jref['postprocess']['decimate']}")
            else:
                print(f"ok   {what}: the streamed bytes, "
                      f"{j['postprocess']['decimate']['triangles_after']} triangles")
            os.remove(out)
        os.remove(ref)


def blob(path, n=44):
    """f32: an ellipsoid with bumps, one closed component when padded."""
    t = (np.arange(n, dtype=np.float32) - (n - 1) / 2) / (n / 2)
    z, y, x = np.meshgrid(t, t, t, indexing="ij")
    f = (x / 0.8) ** 2 + (y / 0.6) ** 2 + (z / 0.7) ** 2 + 0.08 * np.sin(9 * x) * np.cos(7 * y)
    f.astype("<f4").tofile(path)
    return n


def sinc_vs_vtk(exe, work):
    """--smooth N against vtkWindowedSincPolyDataFilter with N iterations."""
    n = blob(os.path.join(work, "blob.raw"))
    src = ["blob.raw", "--raw", f"{n},{n},{n}:f32", "--iso", "1", "--pad"]
    rc, _, err = run(exe, ["extract", *src, "-q", "-o", "blob.ply"], work)
    if rc:
        fail("sinc", f"extract failed: {err.strip()}")
        return
    poly = read_poly(os.path.join(work, "blob.ply"))
    p0 = vtk_to_numpy(poly.GetPoints().GetData()).astype(float)
    centre = 0.5 * (p0.min(0) + p0.max(0))

    def vtk_sinc(iterations):
        f = vtk.vtkWindowedSincPolyDataFilter()
        f.SetInputData(poly)
        f.SetNumberOfIterations(iterations)
        f.SetPassBand(0.1)
        f.NormalizeCoordinatesOn()
        f.BoundarySmoothingOff()
        f.FeatureEdgeSmoothingOff()
        f.NonManifoldSmoothingOn()
        f.Update()
        return vtk_to_numpy(f.GetOutput().GetPoints().GetData()).astype(float)

    def differs(ours, theirs):
        """Mean and largest distance of ours from theirs once VTK's shrink (the
        best scale about the centre) and isomend's volume restoration (the best
        offset along the normals) are taken out."""
        s = ((ours - centre) * (theirs - centre)).sum() / ((theirs - centre) ** 2).sum()
        scaled = centre + s * (theirs - centre)
        out = vtk.vtkPolyData()
        out.DeepCopy(poly)
        pts = vtk.vtkPoints()
        pts.SetData(numpy_to_vtk(scaled, deep=True))
        out.SetPoints(pts)
        nf = vtk.vtkPolyDataNormals()
        nf.SetInputData(out)
        nf.ComputePointNormalsOn()
        nf.SplittingOff()
        nf.ConsistencyOff()
        nf.AutoOrientNormalsOff()
        nf.Update()
        nrm = vtk_to_numpy(nf.GetOutput().GetPointData().GetNormals()).astype(float)
        delta = ((ours - scaled) * nrm).sum() / (nrm * nrm).sum()
        d = np.linalg.norm(ours - (scaled + delta * nrm), axis=1)
        return d.mean(), d.max(), s, delta

    for it in (5, 20):
        rc, out, err = run(exe, ["extract", *src, "-q", "--smooth", str(it), "-o", f"blob_s{it}.ply",
                                 "--json", "-"], work)
        if rc:
            fail("sinc", f"--smooth {it} failed: {err.strip()}")
            continue
        sm = json.loads(out)["postprocess"]["smooth"]
        if sm["moved_vertices"] != len(p0):
            fail("sinc", f"blob: {len(p0) - sm['moved_vertices']} locked vertices (want none)")
        ours = vtk_to_numpy(read_poly(os.path.join(work, f"blob_s{it}.ply")).GetPoints().GetData())
        ours = ours.astype(float)
        theirs = vtk_sinc(it)
        moved = np.linalg.norm(theirs - p0, axis=1)
        mean, largest, s, delta = differs(ours, theirs)
        print(f"  sinc {it}: VTK moves {moved.mean():.4f} mean, {moved.max():.4f} max; isomend "
              f"differs by {mean:.5f} mean, {largest:.5f} max (VTK scaled by {s:.6f}, "
              f"offset {delta:.5f} along the normals)")
        if not (mean <= 0.1 * moved.mean() and largest <= 0.15 * moved.max()):
            fail("sinc", f"--smooth {it} is not VTK's windowed sinc: differs by {mean:.5f} mean, "
                 f"{largest:.5f} max; VTK moves {moved.mean():.5f}, {moved.max():.5f}")
        other = vtk_sinc(2 * it)
        mean2 = differs(ours, other)[0]
        print(f"  sinc {it} against VTK at {2 * it}: differs by {mean2:.5f} mean")
        if mean2 <= 0.1 * moved.mean():
            fail("sinc", f"--smooth {it} matches VTK at {2 * it} iterations too: the comparison "
                 "cannot tell filters apart")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--isomend-mpi")
    ap.add_argument("--mpirun", default="mpirun")
    ap.add_argument("--samples", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    exe = os.path.abspath(a.isomend)
    samples = os.path.abspath(a.samples)
    work = os.path.abspath(a.work)
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)

    self_test_checkers()
    sinc_vs_vtk(exe, work)
    anat = os.path.join(samples, "anatomical.nrrd")
    n = ct_phantom(os.path.join(work, "ct.raw"))
    m = noise(os.path.join(work, "noise.raw"))
    cases = [
        Case("mri", [anat, "--pad"]),
        Case("ct", ["ct.raw", "--raw", f"{n},{n},{n}:i16", "--spacing", "0.7,0.7,1.25", "--iso", "300",
                    "--pad"]),
        Case("noise", ["noise.raw", "--raw", f"{m},{m},{m}:u8", "--iso", "127.5", "--pad"]),
        Case("f1", ["builtin:f1", "--iso", "0", "--pad"]),
        Case("f2", ["builtin:f2", "--iso", "0", "--pad"]),
        Case("mri_open", [anat], border=True),
        Case("mri_mc", [anat, "--pad", "--method", "mc"], border=True),
    ]
    for case in cases:
        test_case(exe, work, case, CONFIGS)
    test_errors(exe, a.isomend_mpi and os.path.abspath(a.isomend_mpi), a.mpirun, work, samples)
    if a.isomend_mpi:
        mpi_decimate(exe, os.path.abspath(a.isomend_mpi), a.mpirun, work,
                     [c for c in cases if c.name in ("mri", "ct", "noise", "mri_open")])
    return clitest.summary(ok="postprocess: ok")


if __name__ == "__main__":
    sys.exit(main())
