"""Independent peers agree with isomend's vertices.

On sphere, torus and gyroid volumes, every MC and DMC vertex of isomend must
sit on the same grid edge, at the same place (float tolerance), as a vertex of
VTK's vtkFlyingEdges3D and of scikit-image's marching_cubes (Lorensen), and the
sets of intersected edges must be equal: one vertex per intersected edge.
Usage: test_peers.py DUMP_MESH_EXE WORKDIR
"""
import os
import subprocess
import sys

import numpy as np


def fields(n=36):
    i = np.arange(n, dtype=np.float64)
    z, y, x = np.meshgrid(i, i, i, indexing="ij")  # array[z, y, x], x fastest
    c = (n - 1) / 2.0
    sphere = np.sqrt((x - c) ** 2 + (y - c * 0.9) ** 2 + (z - c * 1.1) ** 2) - n * 0.31
    rr = np.sqrt((x - c) ** 2 + (y - c) ** 2)
    torus = np.sqrt((rr - n * 0.27) ** 2 + (z - c) ** 2) - n * 0.11
    s = 2 * np.pi * 2.3 / n
    gyroid = np.sin(x * s) * np.cos(y * s) + np.sin(y * s) * np.cos(z * s) + np.sin(z * s) * np.cos(x * s)
    return {"sphere": (sphere, 0.0), "torus": (torus, 0.0), "gyroid": (gyroid + 0.1, 0.0)}


def edge_map(points):
    """Maps each vertex to its grid edge: key (i, j, k, axis) -> fraction along the edge."""
    p = np.asarray(points, dtype=np.float64)
    frac = p - np.round(p)
    on_grid = np.abs(frac) < 1e-6
    out = {}
    for q, g in zip(p, on_grid):
        if g.sum() < 2:
            raise AssertionError("vertex %s is not on a grid edge" % (q,))
        axis = int(np.argmin(g)) if g.sum() == 2 else None
        if axis is None:  # exactly on a sample: cannot happen without ties
            raise AssertionError("vertex %s lies on a sample" % (q,))
        base = np.round(q).astype(int)
        base[axis] = int(np.floor(q[axis]))
        key = (base[0], base[1], base[2], axis)
        if key in out:
            raise AssertionError("two vertices on edge %s" % (key,))
        out[key] = q[axis] - base[axis]
    return out


def compare(name, ours, theirs, peer):
    a, b = edge_map(ours), edge_map(theirs)
    if set(a) != set(b):
        raise AssertionError("%s: %s: intersected edges differ (%d vs %d, %d only in isomend, %d only in peer)"
                             % (name, peer, len(a), len(b), len(set(a) - set(b)), len(set(b) - set(a))))
    worst = max(abs(a[k] - b[k]) for k in a)
    if worst > 2e-5:
        raise AssertionError("%s: %s: positions differ by up to %g" % (name, peer, worst))
    print("  %-7s %-12s %6d vertices agree (max diff %.2g)" % (name, peer, len(a), worst))


def vtk_points(vol, iso):
    import vtk
    from vtk.util import numpy_support
    nz, ny, nx = vol.shape
    img = vtk.vtkImageData()
    img.SetDimensions(nx, ny, nz)
    arr = numpy_support.numpy_to_vtk(np.ascontiguousarray(vol).ravel(), deep=True)
    img.GetPointData().SetScalars(arr)
    fe = vtk.vtkFlyingEdges3D()
    fe.SetInputData(img)
    fe.SetValue(0, iso)
    fe.ComputeNormalsOff()
    fe.ComputeGradientsOff()
    fe.Update()
    return numpy_support.vtk_to_numpy(fe.GetOutput().GetPoints().GetData()).astype(np.float64)


def skimage_points(vol, iso):
    from skimage import measure
    verts, faces, _, _ = measure.marching_cubes(vol, iso, method="lorensen")
    return verts[:, ::-1].astype(np.float64)  # (z, y, x) -> (x, y, z)


def main():
    exe, work = sys.argv[1], sys.argv[2]
    os.makedirs(work, exist_ok=True)
    for name, (vol, iso) in fields().items():
        vol = vol.astype(np.float32)
        raw = os.path.join(work, name + ".raw")
        vol.tofile(raw)
        nz, ny, nx = vol.shape
        peers = {"vtkFlyingEdges3D": vtk_points(vol, iso), "skimage": skimage_points(vol, iso)}
        for method in ("mc", "dmc"):
            prefix = os.path.join(work, "%s_%s" % (name, method))
            subprocess.run([exe, raw, str(nx), str(ny), str(nz), repr(iso), method, prefix], check=True)
            pos = np.fromfile(prefix + ".pos", dtype=np.float32).reshape(-1, 3)
            assert len(pos) > 100, "%s: too few vertices" % name
            for peer, pts in peers.items():
                compare("%s/%s" % (name, method), pos, pts, peer)
    print("peers agree")


if __name__ == "__main__":
    main()
