#!/usr/bin/env python3
"""Label maps: every label's surface from one volume (isomend_labels_extract)
against VTK's vtkDiscreteFlyingEdges3D (all labels in one call) and a
scikit-image loop of marching_cubes over each label's indicator.

The volume: N^3 uint8 Voronoi cells of L labels (seeds uniform in the box,
cached as ~/.cache/isomend-bench/labels-voronoi-N-L.npy), every cell a label
1..L, no background: a segmentation where every voxel belongs to something,
so every cell touches others (the busiest case: every boundary is shared).

What each does, in one process, on the same array:
  isomend  isomend_labels_extract(), labels NULL (every label), DMC, padded,
           normals on, `threads` threads; one closed surface a label.
  vtk      vtkDiscreteFlyingEdges3D on the array padded once beforehand (a
           layer of 0, no label), one contour value a label, normals and
           scalars on (the scalars tell the labels apart), vtkSMPTools
           initialised to `threads`.
  skimage  for each label: its bounding box (scipy.ndimage.find_objects,
           once beforehand) grown by one voxel and padded, the indicator
           (box == L), marching_cubes(level 0.5, method lewiner); one thread
           (scikit-image has none).  Without the boxes each label would cost
           a pass over the whole volume.

Times are medians of --repeats runs, isomend and VTK alternated; ratios are
peer / isomend at equal threads.  Run:
    /usr/bin/python3 bench/labels_bench.py --lib-dir build/libcore [--size 512 --labels 100]
"""
import argparse
import ctypes
import os
import statistics
import sys
import time

import numpy as np

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--lib-dir", default=os.environ.get("ISOMEND_LIB_DIR", "build/libcore"))
ap.add_argument("--size", type=int, default=512)
ap.add_argument("--labels", type=int, default=100)
ap.add_argument("--threads", default="1,2", help="thread counts, comma separated")
ap.add_argument("--repeats", type=int, default=3)
ap.add_argument("--no-skimage", action="store_true")
ap.add_argument("--no-vtk", action="store_true")
ap.add_argument("--check", action="store_true",
                help="fail unless every label's surface is closed (isomend_mesh_check) and the "
                     "peers' triangle totals are within 1 %% of isomend's (the smoke test)")
ap.add_argument("--cache", default=os.path.expanduser("~/.cache/isomend-bench"),
                help="where the volume is kept")
args = ap.parse_args()


class Volume(ctypes.Structure):
    _fields_ = [("data", ctypes.c_void_p), ("type", ctypes.c_int),
                ("dims", ctypes.c_int64 * 3), ("strides", ctypes.c_int64 * 3),
                ("spacing", ctypes.c_double * 3), ("origin", ctypes.c_double * 3),
                ("slice_origins", ctypes.c_void_p)]


class Report(ctypes.Structure):
    _fields_ = [(n, ctypes.c_uint64) for n in (
        "vertices", "triangles", "edges", "border_edges", "hole_edges", "hole_loops",
        "nonmanifold_edges", "misoriented_edges", "nonmanifold_vertices",
        "degenerate_triangles", "components")] + [("euler", ctypes.c_int64)]


class Options(ctypes.Structure):
    _fields_ = [("iso", ctypes.c_double), ("method", ctypes.c_int), ("flags", ctypes.c_uint),
                ("threads", ctypes.c_int), ("progress", ctypes.c_void_p),
                ("progress_user", ctypes.c_void_p)]


def load_lib():
    lib = ctypes.CDLL(os.path.join(args.lib_dir, "libisomend.so"))
    P = ctypes.POINTER
    lib.isomend_volume_init.argtypes = [P(Volume), ctypes.c_void_p, ctypes.c_int, ctypes.c_int64,
                                        ctypes.c_int64, ctypes.c_int64]
    lib.isomend_options_init.argtypes = [P(Options)]
    lib.isomend_labels_extract.argtypes = [P(Volume), ctypes.c_void_p, ctypes.c_size_t,
                                           P(Options), P(ctypes.c_void_p)]
    lib.isomend_labels_count.argtypes = [ctypes.c_void_p]
    lib.isomend_labels_count.restype = ctypes.c_size_t
    lib.isomend_labels_mesh.argtypes = [ctypes.c_void_p, ctypes.c_size_t]
    lib.isomend_labels_mesh.restype = ctypes.c_void_p
    lib.isomend_mesh_triangle_count.argtypes = [ctypes.c_void_p]
    lib.isomend_mesh_triangle_count.restype = ctypes.c_size_t
    lib.isomend_labels_destroy.argtypes = [ctypes.c_void_p]
    lib.isomend_mesh_check.argtypes = [ctypes.c_void_p, P(Report)]
    lib.isomend_version.restype = ctypes.c_char_p
    return lib


def voronoi(n, cells, seed=36):
    path = os.path.join(args.cache, f"labels-voronoi-{n}-{cells}.npy")
    if os.path.exists(path):
        return np.load(path)
    rng = np.random.default_rng(seed)
    s = (rng.random((cells, 3)) * n).astype(np.float64)
    out = np.empty((n, n, n), np.uint8 if cells < 256 else np.uint16)
    y, x = np.mgrid[0:n, 0:n].astype(np.float64)
    pts = np.stack([x.ravel(), y.ravel()], 1)
    for z in range(n):  # nearest seed, a slice at a time
        d = ((pts[:, None, 0] - s[None, :, 0]) ** 2 + (pts[:, None, 1] - s[None, :, 1]) ** 2 +
             (z - s[None, :, 2]) ** 2)
        out[z] = (d.argmin(1) + 1).reshape(n, n)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    np.save(path, out)
    return out


def isomend_run(lib, a, threads, check=False):
    vol = Volume()
    lib.isomend_volume_init(ctypes.byref(vol), a.ctypes.data, 0, a.shape[2], a.shape[1], a.shape[0])
    opts = Options()
    lib.isomend_options_init(ctypes.byref(opts))
    opts.flags = 4  # ISOMEND_FLAG_PAD
    opts.threads = threads
    res = ctypes.c_void_p()
    t0 = time.perf_counter()
    st = lib.isomend_labels_extract(ctypes.byref(vol), None, 0, ctypes.byref(opts), ctypes.byref(res))
    dt = time.perf_counter() - t0
    if st:
        sys.exit(f"isomend_labels_extract: status {st}")
    n = lib.isomend_labels_count(res)
    tris = sum(lib.isomend_mesh_triangle_count(lib.isomend_labels_mesh(res, q)) for q in range(n))
    bad = []
    for q in range(n if check else 0):
        r = Report()
        lib.isomend_mesh_check(lib.isomend_labels_mesh(res, q), ctypes.byref(r))
        if r.hole_edges or r.border_edges or r.nonmanifold_edges or r.misoriented_edges:
            bad.append(q)
    lib.isomend_labels_destroy(res)
    if bad:
        sys.exit(f"isomend: labels {bad} not closed")
    return dt, n, tris


def vtk_setup(a, labels):
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk
    p = np.pad(a, 1)  # 0 is no label: the padding layer
    img = vtk.vtkImageData()
    img.SetDimensions(p.shape[2], p.shape[1], p.shape[0])
    img.GetPointData().SetScalars(numpy_to_vtk(p.ravel(), deep=False))

    def run(threads):
        vtk.vtkSMPTools.Initialize(threads)
        f = vtk.vtkDiscreteFlyingEdges3D()
        f.SetInputData(img)
        for i, L in enumerate(labels):
            f.SetValue(i, float(L))
        f.ComputeNormalsOn()
        f.ComputeScalarsOn()
        t0 = time.perf_counter()
        f.Update()
        dt = time.perf_counter() - t0
        return dt, f.GetOutput().GetNumberOfPolys()
    return run, (p, img)


def skimage_run(a, labels):
    from scipy.ndimage import find_objects
    from skimage.measure import marching_cubes
    boxes = find_objects(a)
    t0 = time.perf_counter()
    tris = 0
    for L in labels:
        sl = boxes[L - 1]
        lo = [max(s.start - 1, 0) for s in sl]
        hi = [min(s.stop + 1, n) for s, n in zip(sl, a.shape)]
        ind = np.pad(a[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] == L, 1).astype(np.uint8)
        verts, faces, normals, values = marching_cubes(ind, level=0.5, method="lewiner")
        tris += len(faces)
    return time.perf_counter() - t0, tris


def main():
    lib = load_lib()
    t0 = time.perf_counter()
    a = voronoi(args.size, args.labels)
    labels = [int(x) for x in np.unique(a)]
    print(f"volume: {args.size}^3 uint8 Voronoi, {len(labels)} labels "
          f"(made or loaded in {time.perf_counter() - t0:.1f} s); isomend "
          f"{lib.isomend_version().decode()}, {os.cpu_count()} CPUs, load "
          f"{os.getloadavg()[0]:.2f}", flush=True)
    vrun = None if args.no_vtk else vtk_setup(a, labels)[0]
    rows = []
    for t in [int(x) for x in args.threads.split(",")]:
        iso_t, vtk_t = [], []
        for r in range(args.repeats):
            dt, n, tris = isomend_run(lib, a, t, args.check and r == 0)
            iso_t.append(dt)
            if vrun and r < max(1, (args.repeats + 1) // 2):
                vt, vtris = vrun(t)
                vtk_t.append(vt)
        mi = statistics.median(iso_t)
        line = f"threads {t}: isomend {mi * 1000:.0f} ms ({n} labels, {tris} triangles)"
        if vtk_t:
            mv = statistics.median(vtk_t)
            line += (f"; vtkDiscreteFlyingEdges3D {mv * 1000:.0f} ms ({vtris} triangles): "
                     f"{mv / mi:.1f}x")
        print(line, flush=True)
        rows.append((t, mi, statistics.median(vtk_t) if vtk_t else None, tris))
        if args.check and n != len(labels):
            sys.exit(f"isomend: {n} labels, the volume has {len(labels)}")
        if args.check and vtk_t and abs(vtris - tris) > 0.01 * tris:
            sys.exit(f"VTK's {vtris} triangles are not within 1 % of isomend's {tris}")
    if not args.no_skimage:
        st, stris = skimage_run(a, labels)
        mi1 = rows[0][1]
        print(f"scikit-image marching_cubes per label (bounding boxes, 1 thread): {st * 1000:.0f} ms "
              f"({stris} triangles): {st / mi1:.1f}x isomend at {rows[0][0]} thread(s)", flush=True)
        if args.check and abs(stris - rows[0][3]) > 0.01 * rows[0][3]:
            sys.exit(f"scikit-image's {stris} triangles are not within 1 % of isomend's")


if __name__ == "__main__":
    main()
