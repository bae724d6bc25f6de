#!/usr/bin/env python3
"""DICOM series meshed at their slices' true positions: an exact check.

Usage: test_dicom_positions.py ISOMEND_CLI DICOM_DIR

For gen_dicom.py's series whose slices are not evenly spaced ("rounded":
positions written to 0.1 mm on an oblique MR; "two_spacings": 2.5 then 5 mm;
"tilt15": a 15 degree gantry tilt; "missing_slice"; "irregular"):

- `isomend info --json` gives the slice origins the generator meant (within
  1e-9), the geometry, and the warning exactly where one is due;
- `isomend extract` (padded) writes the mesh with one warning line on stderr
  where due, exit 0, and the mesh is closed (its continuity check in --json);
- the mesh's triangles are those of the same pixels meshed on the uniform
  index grid (the raw twin with the series' spacing and origin);
- every vertex is, bit for bit, the vertex of the index grid's mesh mapped
  through the slices' positions: its edge is found exactly in the index
  mesh (the float the core computes there for each candidate edge must be
  the stored one), t = (iso - f0) / (f1 - f0) is recomputed from the
  samples, the position is (1 - t) p0 + t p1 of the samples' true positions
  (isomend.h, "Slices where they are"; padding one gap beyond the ends,
  padded ends cut at the middle), rounded once, then mapped to patient space
  as isomend_mesh_copy_transformed does;
- streamed (--max-memory) the same bytes.
"""
import json
import os
import sys
import tempfile

import numpy as np

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from clitest import check, failures, read_ply_arrays, run as run_cli, summary  # noqa: E402
from vtkcheck import components, feature_edges, read_poly  # noqa: E402

CLI, DIR = sys.argv[1], os.path.abspath(sys.argv[2])
CASES = json.load(open(os.path.join(DIR, "cases.json")))
TYPES = {"u8": "u1", "i8": "i1", "u16": "<u2", "i16": "<i2", "i32": "<i4", "f32": "<f4", "f64": "<f8"}
NAMES = ["rounded", "two_spacings", "tilt15", "missing_slice", "irregular"]


def run(args):
    return run_cli(CLI, args)


def marched_origins(so):
    """The marched slices' origins with padding: one gap beyond each end,
    computed as the core does (so[0] - (so[1] - so[0]), ...)."""
    lo = so[0] - (so[1] - so[0])
    hi = so[-1] + (so[-1] - so[-2])
    return np.vstack([lo, so, hi])


def exact_vertices(name, c, j, dv, rv, iso):
    """The mesh's vertices dv against the index mesh rv (uniform spacing h,
    origin o), both padded; j: info's JSON (slice origins, world transform)."""
    nx, ny, nz = c["dims"]
    vol = np.fromfile(c["expected"], TYPES[c["type"]]).astype(np.float64).reshape(nz, ny, nx)
    padded = np.full((nz + 2, ny + 2, nx + 2), np.nan)
    padded[1:-1, 1:-1, 1:-1] = vol
    h = np.array(j["spacing"], dtype=np.float64)
    o = np.array(j["origin"], dtype=np.float64) - h  # the marched grid's origin (pad 1)
    so = marched_origins(np.array(j["slice_origins"], dtype=np.float64))
    U = rv[:, :3].astype(np.float64)
    n = len(U)
    u = (U - o) / h  # approximate marched indices
    found = np.zeros(n, bool)
    want = np.zeros((n, 3), np.float64)
    grad_want = np.zeros((n, 3), np.float64)
    for axis in range(3):
        for shift in (0, -1):
            L = np.rint(u).astype(np.int64)
            L[:, axis] = np.floor(u[:, axis] + 1e-9).astype(np.int64) + shift
            hi = L.copy()
            hi[:, axis] += 1
            ok = ~found & np.all(L >= 0, 1) & np.all(hi < [nx + 2, ny + 2, nz + 2], 1)
            idx = np.nonzero(ok)[0]
            f0 = padded[L[idx, 2], L[idx, 1], L[idx, 0]]
            f1 = padded[hi[idx, 2], hi[idx, 1], hi[idx, 0]]
            nan = np.isnan(f0) | np.isnan(f1)
            with np.errstate(invalid="ignore", divide="ignore"):
                t = np.where(nan, 0.5, (iso - f0) / (f1 - f0))
            crossing = nan | ((f0 >= iso) != (f1 >= iso))
            # the uniform grid's float for this edge, as the core computes it
            x = L[idx].astype(np.float64)
            x[:, axis] += t
            uni = (o + x * h).astype(np.float32)
            match = crossing & np.all(uni == rv[idx, :3], 1) & ((t >= 0) & (t <= 1) | nan)
            sel = idx[match]
            t = t[match]
            Ls, His = L[sel], hi[sel]
            w0 = so[Ls[:, 2]].copy()
            w0[:, 0] += (Ls[:, 0] - 1) * h[0]
            w0[:, 1] += (Ls[:, 1] - 1) * h[1]
            w1 = so[His[:, 2]].copy()
            w1[:, 0] += (His[:, 0] - 1) * h[0]
            w1[:, 1] += (His[:, 1] - 1) * h[1]
            want[sel] = (1.0 - t)[:, None] * w0 + t[:, None] * w1
            found[sel] = True
    check(found.all(), "%s: %d of %d index-mesh vertices match no grid edge" % (name, (~found).sum(), n))
    grid = want.astype(np.float32).astype(np.float64)
    A = np.array(j["world_transform"], dtype=np.float64).reshape(3, 4) if j["world_transform"] else None
    if A is not None:  # isomend_mesh_copy_transformed: m[0] x + m[1] y + m[2] z + m[3], in double
        world = np.empty_like(grid)
        for r in range(3):
            world[:, r] = A[r, 0] * grid[:, 0] + A[r, 1] * grid[:, 1] + A[r, 2] * grid[:, 2] + A[r, 3]
        expect = world.astype(np.float32)
    else:
        expect = grid.astype(np.float32)
    bad = np.nonzero(np.any(expect != dv[:, :3], 1) & found)[0]
    check(len(bad) == 0, "%s: %d of %d vertices are not the index mesh's mapped through the slices' "
          "positions (first %s: %s, expected %s)" % (name, len(bad), n, bad[:1],
                                                     dv[bad[:1], :3].tolist(), expect[bad[:1]].tolist()))
    return int(found.sum())


def main():
    with tempfile.TemporaryDirectory() as tmp:
        exact = 0
        for name in NAMES:
            c = CASES.get(name)
            check(c is not None and c["ok"], "%s: not a good case of gen_dicom.py" % name)
            if not c or not c["ok"]:
                continue
            r = run(["info", "--json", "-", "--quiet"] + c["sources"])
            check(r.returncode == 0, "%s: info exit %d: %s" % (name, r.returncode, r.stderr))
            if r.returncode:
                continue
            j = json.loads(r.stdout)
            so = j.get("slice_origins")
            check(so is not None and np.allclose(so, c["slice_origins"], rtol=1e-9, atol=1e-9),
                  "%s: slice origins %s, expected %s" % (name, so and so[:2], c["slice_origins"][:2]))
            g = j["geometry"]
            check(not g["uniform"] and (g["warning"] != "") == c["warning"],
                  "%s: geometry %s (warning expected: %s)" % (name, g, c["warning"]))
            if name == "tilt15":
                check(abs(g["tilt_degrees"] - 15) < 1e-6, "tilt15: tilt %s" % g["tilt_degrees"])
            iso = 300.0 if j["dicom"]["hounsfield"] else 0.5 + np.floor(
                np.median(np.fromfile(c["expected"], TYPES[c["type"]])))
            isos = "%.17g" % iso
            d = os.path.join(tmp, name + ".ply")
            r = run(["extract", "--pad", "--in-memory", "--iso", isos, "-o", d, "--json", "-"] +
                    c["sources"])
            check(r.returncode == 0, "%s: extract exit %d: %s" % (name, r.returncode, r.stderr))
            if r.returncode:
                continue
            warn = [l for l in r.stderr.splitlines() if "warning" in l]
            check(len(warn) == (1 if c["warning"] else 0) and
                  (not warn or warn[0].startswith("isomend: warning: ")),
                  "%s: warning lines %s" % (name, warn))
            e = json.loads(r.stdout)
            ck = e.get("check") or {}
            check(ck.get("holes") == 0 and ck.get("border_edges") == 0 and ck.get("continuous") is True and
                  ck.get("nonmanifold_edges") == 0 and ck.get("misoriented_edges") == 0,
                  "%s: the padded mesh is not closed: %s" % (name, ck))
            poly = read_poly(d)
            fe = feature_edges(poly)
            check(fe == (0, 0) and components(poly) == ck.get("components"),
                  "%s: VTK finds %d boundary and %d non-manifold edges, %d components (checker: %s)"
                  % (name, fe[0], fe[1], components(poly), ck.get("components")))
            nx, ny, nz = c["dims"]
            rp = os.path.join(tmp, name + ".index.ply")
            r = run(["extract", "--quiet", "--pad", "--iso", isos, "-o", rp, c["expected"],
                     "--raw", "%d,%d,%d:%s" % (nx, ny, nz, c["type"]),
                     "--spacing", ",".join("%.17g" % v for v in j["spacing"]),
                     "--origin", ",".join("%.17g" % v for v in j["origin"])])
            check(r.returncode == 0, "%s: raw twin: %s" % (name, r.stderr))
            if r.returncode:
                continue
            dv, dt = read_ply_arrays(d)
            rv, rt = read_ply_arrays(rp)
            check(dv.shape == rv.shape and np.array_equal(dt, rt),
                  "%s: %s vertices / %d triangles against the index grid's %s / %d" %
                  (name, dv.shape, len(dt), rv.shape, len(rt)))
            if dv.shape != rv.shape:
                continue
            exact += exact_vertices(name, c, j, dv, rv, iso)
            # streamed: the same bytes
            s = os.path.join(tmp, name + ".streamed.ply")
            r = run(["extract", "--quiet", "--pad", "--iso", isos, "-o", s, "--json", "-", "--max-memory",
                     str((e["memory_estimate"] + e["memory_streaming"]) // 2)] + c["sources"])
            check(r.returncode == 0 and json.loads(r.stdout)["streamed"] and
                  open(s, "rb").read() == open(d, "rb").read(),
                  "%s: the streamed mesh differs: %s" % (name, r.stderr))
        print("%d vertices of %d series checked exactly" % (exact, len(NAMES)))
        check(exact > 5000, "too few vertices checked: %d" % exact)
    return summary(failures)


if __name__ == "__main__":
    sys.exit(main())
