#!/usr/bin/env python3
"""Post-processing benchmark: isomend's decimation and smoothing against peers,
on the same meshes, in one run (docs/postprocess.md).

Meshes (each isomend's padded DMC surface, closed and oriented): the bundled
MRI, a CT-like phantom (i16 HU: hollow bone balls, a bone torus, fragments in
soft tissue, noise) at 160^3 (64 k triangles) and at 512^3 (a CT's size,
about 0.65 M triangles), and a busy gyroid (about 2.9 M triangles at 256^3).

Decimation to 10 % of the triangles with
  isomend        `isomend extract ... --decimate 0.1` (the decimation step's
                 time from --json postprocess.decimate.ms)
  isomend-stream the same on the stream (--stream --chunk-layers 8: the
                 streamed decimation, chunks of 8 layers; its own calls' time)
  vtk-quadric    vtkQuadricDecimation (TargetReduction 0.9)
  vtk-pro        vtkDecimatePro (TargetReduction 0.9, PreserveTopologyOn,
                 SplittingOff, BoundaryVertexDeletionOff)
  meshopt        meshopt_simplify with meshopt_SimplifyLockBorder
                 (bench/meshopt_simplify.c, when built)
  meshlab        MeshLab 2020.09's "Simplification: Quadric Edge Collapse
                 Decimation" through meshlabserver under Xvfb, Preserve
                 Topology and Boundary, Preserve Normal, optimal placement;
                 meshlabserver logs no filter time: the time is its run's
                 minus a run that only loads and saves the mesh (approximate)
Each tool's time is its decimation alone (no reading or writing).  Each
result is written as PLY and judged: triangles reached; the distance from
the input's vertices to the result (vtkCellLocator), mean and max as a
fraction of the bounding box's diagonal; and `isomend check`'s verdict (hole
edges, non-manifold edges, misoriented edges, components, Euler
characteristic; the input's components and Euler for comparison).

Smoothing: isomend `--smooth 20` against vtkWindowedSincPolyDataFilter (20
iterations, pass band 0.1, normalised coordinates; the same filter as
isomend's): time (the median of 3 alternating runs each) and volume change
(vtkMassProperties).

The machine is a shared, loaded VM: compare tools within a run (ratios),
not absolute times across runs.

usage: postprocess_bench.py --isomend PATH --samples DIR --work DIR [--out FILE.md]
                            [--smoke] [--check] [--peers all|isomend] [--meshopt PATH]
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
XVFB = os.path.join(HERE, "..", "tests", "meshlab", "with_xvfb.py")

MLX = """<!DOCTYPE FilterScript>
<FilterScript>
 <filter name="Simplification: Quadric Edge Collapse Decimation">
  <Param type="RichInt" name="TargetFaceNum" value="{target}"/>
  <Param type="RichFloat" name="TargetPerc" value="0"/>
  <Param type="RichFloat" name="QualityThr" value="0.3"/>
  <Param type="RichBool" name="PreserveBoundary" value="true"/>
  <Param type="RichFloat" name="BoundaryWeight" value="1"/>
  <Param type="RichBool" name="PreserveNormal" value="true"/>
  <Param type="RichBool" name="PreserveTopology" value="true"/>
  <Param type="RichBool" name="OptimalPlacement" value="true"/>
  <Param type="RichBool" name="PlanarQuadric" value="false"/>
  <Param type="RichFloat" name="PlanarWeight" value="0.001"/>
  <Param type="RichBool" name="QualityWeight" value="false"/>
  <Param type="RichBool" name="AutoClean" value="true"/>
  <Param type="RichBool" name="Selected" value="false"/>
 </filter>
</FilterScript>
"""


# ------------------------------------------------------------------ volumes

def ct_phantom(path, n):
    """i16 HU, like tests/cli/test_postprocess.py's phantom (meshed at 300)."""
    rng = np.random.default_rng(11)
    v = np.empty((n, n, n), np.int16)
    y, x = np.mgrid[0:n, 0:n].astype(np.float32)
    c = (n - 1) / 2
    balls = [(0.32, 0.40, 0.35, 0.13), (0.66, 0.55, 0.40, 0.11), (0.45, 0.62, 0.68, 0.10)]
    frags = [(*rng.uniform(0.25, 0.75, 3) * n, rng.uniform(0.9, 2.6) * n / 72) for _ in range(12)]
    tx, ty, tz, R, rr = 0.52 * n, 0.30 * n, 0.72 * n, 0.09 * n, 0.035 * n
    for k in range(n):
        a = np.full((n, n), -1000, np.float32)
        a[((x - c) / (0.46 * n)) ** 2 + ((y - c) / (0.40 * n)) ** 2 + ((k - c) / (0.46 * n)) ** 2 < 1] = 40
        for bx, by, bz, r in balls:
            d = np.sqrt((x - bx * n) ** 2 + (y - by * n) ** 2 + (k - bz * n) ** 2)
            a[d < r * n] = 900
            a[d < 0.6 * r * n] = 150
        q = np.sqrt((x - tx) ** 2 + (y - ty) ** 2) - R
        a[q ** 2 + (k - tz) ** 2 < rr * rr] = 1100
        for fx, fy, fz, r in frags:
            a[(x - fx) ** 2 + (y - fy) ** 2 + (k - fz) ** 2 < r * r] = 700
        a += rng.uniform(-40, 40, a.shape).astype(np.float32)
        v[k] = a
    v.astype("<i2").tofile(path)


SMOOTH_RUNS = 3  # alternating runs of each smoother, the median reported


def gyroid(path, n, periods=4):
    """f32 gyroid, `periods` periods across: about 2.9 M triangles at 256^3."""
    t = np.arange(n, dtype=np.float32) * (2 * np.pi * periods / n)
    y, x = np.meshgrid(t, t, indexing="ij")
    with open(path, "wb") as f:
        for z in t:
            s = np.sin(x) * np.cos(y) + np.sin(y) * np.cos(z) + np.sin(z) * np.cos(x)
            s.astype("<f4").tofile(f)


# ------------------------------------------------------------------ measures

# tests/common/vtkcheck.py, imported when VTK is used (--peers isomend runs without it)
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "common"))


def read_poly(path):
    from vtkcheck import read_poly as vtk_read
    return vtk_read(path)


def write_poly(poly, path):
    import vtk
    w = vtk.vtkPLYWriter()
    w.SetFileName(path)
    w.SetFileTypeToBinary()
    w.SetDataByteOrderToLittleEndian()
    w.SetInputData(poly)
    if not w.Write():
        raise RuntimeError(f"VTK could not write {path}")


def distances(src_poly, dst_poly):
    from vtkcheck import distances as vtk_distances
    return vtk_distances(src_poly, dst_poly)


def ply_positions(path):
    """x y z of isomend's binary PLY (float properties, x y z first)."""
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    head = data[:end].decode().splitlines()
    nv = int(next(ln.split()[2] for ln in head if ln.startswith("element vertex")))
    nprops = sum(1 for ln in head if ln.startswith("property float"))
    return np.frombuffer(data, "<f4", nv * nprops, end).reshape(nv, nprops)[:, :3]


def volume(poly):
    import vtk
    mp = vtk.vtkMassProperties()
    mp.SetInputData(poly)
    mp.Update()
    return mp.GetVolume()


def check(exe, path):
    p = subprocess.run([exe, "check", path, "--json", "-"], capture_output=True, text=True)
    try:
        return json.loads(p.stdout)["check"]
    except (ValueError, KeyError):
        return {"error": p.stderr.strip()[-200:]}


# ------------------------------------------------------------------ tools

def run_isomend(a, src_args, out, streamed=False):
    extra = ["--stream", "--chunk-layers", "8"] if streamed else []
    p = subprocess.run([a.isomend, "extract", *src_args, "-q", "--decimate", "0.1", *extra, "-o",
                        out, "--json", "-"], capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(p.stderr.strip())
    j = json.loads(p.stdout)
    return j["postprocess"]["decimate"]["ms"], j


def run_vtk(kind, inp, out):
    import vtk
    poly = read_poly(inp)
    if kind == "vtk-quadric":
        f = vtk.vtkQuadricDecimation()
        f.SetTargetReduction(0.9)
    else:
        f = vtk.vtkDecimatePro()
        f.SetTargetReduction(0.9)
        f.PreserveTopologyOn()
        f.SplittingOff()
        f.BoundaryVertexDeletionOff()
    f.SetInputData(poly)
    t0 = time.perf_counter()
    f.Update()
    ms = (time.perf_counter() - t0) * 1e3
    write_poly(f.GetOutput(), out)
    return ms


def run_meshopt(exe, inp, out):
    p = subprocess.run([exe, inp, out, "0.1"], capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(p.stderr.strip())
    return float(p.stdout.split()[2])


def run_meshlab(work, inp, out, target):
    script = os.path.join(work, "quadric.mlx")
    with open(script, "w") as f:
        f.write(MLX.format(target=target))
    log = os.path.join(work, "meshlab_log.txt")
    if os.path.exists(log):
        os.remove(log)
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, XVFB, "meshlabserver", "-i", inp, "-o", out, "-s", script,
                        "-l", log], capture_output=True, text=True, timeout=1800)
    wall = (time.perf_counter() - t0) * 1e3
    if p.returncode or not os.path.exists(out):
        raise RuntimeError(f"meshlabserver exit {p.returncode}: {p.stdout[-300:]} {p.stderr[-300:]}")
    # meshlabserver 2020.09 logs no filter time: subtract a run that only
    # loads and saves the same mesh (Xvfb's start included in both)
    t0 = time.perf_counter()
    q = subprocess.run([sys.executable, XVFB, "meshlabserver", "-i", inp, "-o",
                        os.path.join(work, "meshlab_copy.ply")], capture_output=True, text=True,
                       timeout=1800)
    base = (time.perf_counter() - t0) * 1e3
    if q.returncode:
        raise RuntimeError(f"meshlabserver (load and save) exit {q.returncode}")
    return max(wall - base, 0.0)


def fmt_ms(ms):
    return f"{ms / 1000:.2f} s" if ms >= 1000 else f"{ms:.0f} ms"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--samples", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--out")
    ap.add_argument("--smoke", action="store_true", help="small meshes, seconds")
    ap.add_argument("--check", action="store_true",
                    help="fail unless every tool ran and isomend's meshes are closed")
    ap.add_argument("--peers", default="all", choices=["all", "isomend"])
    ap.add_argument("--meshopt", help="isomend_bench_meshopt (bench/meshopt_simplify.c)")
    a = ap.parse_args()
    a.isomend = os.path.abspath(a.isomend)
    work = os.path.abspath(a.work)
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    problems = []

    # the CT phantom twice: small (64 k triangles) and at a CT's size (512^3:
    # about 0.65 M triangles, the size of a 256 x 256 x 108 CT's bone surface)
    n_cts, n_gy = ((48,), 48) if a.smoke else ((160, 512), 256)
    for n_ct in n_cts:
        ct_phantom(os.path.join(work, f"ct{n_ct}.raw"), n_ct)
    gyroid(os.path.join(work, "gyroid.raw"), n_gy)
    meshes = [("MRI (anatomical.nrrd)", [os.path.join(os.path.abspath(a.samples), "anatomical.nrrd"), "--pad"])]
    meshes += [(f"CT phantom {n_ct}^3 i16", [os.path.join(work, f"ct{n_ct}.raw"), "--raw",
                                              f"{n_ct},{n_ct},{n_ct}:i16", "--iso", "300", "--pad"])
               for n_ct in n_cts]
    meshes.append((f"gyroid {n_gy}^3 f32", [os.path.join(work, "gyroid.raw"), "--raw",
                                             f"{n_gy},{n_gy},{n_gy}:f32", "--iso", "0", "--pad"]))
    tools = ["isomend", "isomend-stream"]
    if a.peers == "all":
        tools += ["vtk-quadric", "vtk-pro"]
        if a.meshopt:
            tools.append("meshopt")
        elif a.check:
            print("note: no --meshopt (libmeshoptimizer-dev not installed): meshoptimizer skipped")
        if shutil.which("meshlabserver") and shutil.which("Xvfb"):
            tools.append("meshlab")
        else:
            problems.append("meshlabserver or Xvfb missing")

    rows, smooth_rows = [], []
    for label, src in meshes:
        inp = os.path.join(work, "input.ply")
        p = subprocess.run([a.isomend, "extract", *src, "-q", "-o", inp, "--json", "-"],
                           capture_output=True, text=True)
        if p.returncode:
            sys.exit(f"isomend extract failed: {p.stderr}")
        j0 = json.loads(p.stdout)
        c0 = j0["check"]
        vtk_ok = a.peers == "all"  # isomend alone: no VTK needed, isomend's own measures
        ipoly = read_poly(inp) if vtk_ok else None
        xyz = ply_positions(inp)
        diag = float(np.linalg.norm(xyz.max(axis=0) - xyz.min(axis=0)))
        ntri = j0["triangles"]
        print(f"{label}: {ntri} triangles, {c0['components']} components, Euler {c0['euler']}", flush=True)
        for tool in tools:
            out = os.path.join(work, f"out_{tool}.ply")
            try:
                if tool.startswith("isomend"):
                    ms, j = run_isomend(a, src, out, streamed=tool == "isomend-stream")
                elif tool.startswith("vtk"):
                    ms = run_vtk(tool, inp, out)
                elif tool == "meshopt":
                    ms = run_meshopt(a.meshopt, inp, out)
                else:
                    ms = run_meshlab(work, inp, out, int(round(0.1 * ntri)))
            except Exception as e:  # noqa: BLE001 - a peer failing is a row, not a crash
                problems.append(f"{label} {tool}: {e}")
                rows.append((label, tool, None, None, None, None, None, str(e)[:80]))
                continue
            c = check(a.isomend, out)
            if vtk_ok:
                opoly = read_poly(out)
                d = distances(ipoly, opoly) / diag
                dmean, dmax = d.mean(), d.max()
                nout = opoly.GetNumberOfCells()
            else:  # isomend's measured distances (the same as VTK's: cli_postprocess)
                dj = j["postprocess"]["decimate"]
                dmean, dmax = dj["mean_error"] / diag, dj["max_error"] / diag
                nout = dj["triangles_after"]
            verdict = ("error: " + c["error"]) if "error" in c else (
                f"{c['holes']} / {c['nonmanifold_edges']} / {c['misoriented_edges']} / "
                f"{c['components']} / {c['euler']}")
            rows.append((label, tool, ms, nout, dmean, dmax, c, verdict))
            print(f"  {tool:12s} {fmt_ms(ms):>9s} {nout:8d} tri  mean {dmean:.2e} "
                  f"max {dmax:.2e}  holes/nm/mis/comp/euler {verdict}", flush=True)
            if tool.startswith("isomend") and ("error" in c or c["holes"] or c["nonmanifold_edges"] or
                                      c["misoriented_edges"] or c["components"] != c0["components"] or
                                      c["euler"] != c0["euler"]):
                problems.append(f"{label} isomend decimated mesh not closed or topology changed: {c}")
        # smoothing: isomend and VTK's windowed sinc (the same filter, N = 20),
        # alternating, the median of SMOOTH_RUNS each (the machine is noisy)
        iso_ms, vtk_ms, sp, sm, v2 = [], [], None, None, None
        for _ in range(SMOOTH_RUNS):
            sp = subprocess.run([a.isomend, "extract", *src, "-q", "--smooth", "20", "-o",
                                 os.path.join(work, "smooth.ply"), "--json", "-"], capture_output=True,
                                text=True)
            if sp.returncode:
                break
            iso_ms.append(json.loads(sp.stdout)["postprocess"]["smooth"]["ms"])
            if a.peers == "all":
                import vtk
                f = vtk.vtkWindowedSincPolyDataFilter()
                f.SetInputData(ipoly)
                f.SetNumberOfIterations(20)
                f.SetPassBand(0.1)
                f.NormalizeCoordinatesOn()
                f.BoundarySmoothingOff()
                f.FeatureEdgeSmoothingOff()
                f.NonManifoldSmoothingOn()
                t0 = time.perf_counter()
                f.Update()
                vtk_ms.append((time.perf_counter() - t0) * 1e3)
                v2 = volume(f.GetOutput())
        if sp.returncode:
            problems.append(f"{label} --smooth 20: {sp.stderr.strip()}")
        else:
            sj = json.loads(sp.stdout)
            sm = sj["postprocess"]["smooth"]
            if vtk_ok:
                v0 = volume(ipoly)
                v1 = volume(read_poly(os.path.join(work, "smooth.ply")))
            else:
                v0, v1 = sm["volume_before"], sm["volume_after"]
            smooth_rows.append((label, "isomend --smooth 20", statistics.median(iso_ms), 100 * (v1 - v0) / v0))
            c = sj["check"]
            if c["holes"] or c["nonmanifold_edges"] or c["misoriented_edges"] or c["euler"] != c0["euler"]:
                problems.append(f"{label} isomend smoothed mesh not closed: {c}")
            if abs(v1 - v0) > 0.005 * abs(v0):
                problems.append(f"{label} isomend smoothing changed the volume {v0} -> {v1}")
            if a.peers == "all":
                smooth_rows.append((label, "vtkWindowedSinc 20, pass band 0.1", statistics.median(vtk_ms),
                                    100 * (v2 - v0) / v0))
            for r in smooth_rows[-2:] if a.peers == "all" else smooth_rows[-1:]:
                print(f"  {r[1]:36s} {fmt_ms(r[2]):>9s} volume {r[3]:+.3f} %", flush=True)
        rows.append((label, "input", None, ntri, None, None, c0,
                     f"{c0['holes']} / {c0['nonmanifold_edges']} / {c0['misoriented_edges']} / "
                     f"{c0['components']} / {c0['euler']}"))

    lines = ["| mesh | tool | time | triangles | mean dist. | max dist. | holes / non-manifold / misoriented / components / Euler |",
             "|---|---|---|---|---|---|---|"]
    order = {t: i for i, t in enumerate(["input", *tools])}
    for label, _ in meshes:
        for r in sorted((r for r in rows if r[0] == label), key=lambda r: order.get(r[1], 99)):
            if r[2] is None and r[1] != "input":
                lines.append(f"| {label} | {r[1]} | failed | | | | {r[7]} |")
            elif r[1] == "input":
                lines.append(f"| {label} | input | | {r[3]} | | | {r[7]} |")
            else:
                lines.append(f"| {label} | {r[1]} | {fmt_ms(r[2])} | {r[3]} | {r[4]:.2e} | {r[5]:.2e} | {r[7]} |")
    lines += ["", "| mesh | smoothing | time | volume change |", "|---|---|---|---|"]
    for label, tool, ms, dv in smooth_rows:
        lines.append(f"| {label} | {tool} | {fmt_ms(ms)} | {dv:+.3f} % |")
    # the ratios the goals name: each peer's time over isomend's, in this run
    if a.peers == "all":
        lines += ["", "| mesh | vtk-quadric / isomend | meshlab / isomend | meshopt / isomend | "
                  "vtkWindowedSinc / isomend --smooth |", "|---|---|---|---|---|"]
        for label, _ in meshes:
            t = {r[1]: r[2] for r in rows if r[0] == label and r[2] is not None}
            sm = {r[1].split()[0]: r[2] for r in smooth_rows if r[0] == label}

            def ratio(x, y):
                return f"{x / y:.1f}x" if x and y else "-"
            lines.append(f"| {label} | {ratio(t.get('vtk-quadric'), t.get('isomend'))} | "
                         f"{ratio(t.get('meshlab'), t.get('isomend'))} | {ratio(t.get('meshopt'), t.get('isomend'))} | "
                         f"{ratio(sm.get('vtkWindowedSinc'), sm.get('isomend'))} |")
    table = "\n".join(lines)
    print()
    print(table)
    if a.out:
        os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
        with open(a.out, "w") as f:
            f.write(table + "\n")
    if a.check and problems:
        for pr in problems:
            print("FAIL:", pr)
        return 1
    for pr in problems:
        print("note:", pr)
    print("postprocess bench: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
