#!/usr/bin/env python3
"""NIfTI sources (io/slices/src/nifti.cpp, libnifti2) through `isomend`.

Usage: test_nifti.py ISOMEND_CLI SAMPLES_DIR DICOM_DIR

Every file is written here with Debian's python3-nibabel (independent of
libnifti), from the bundled MRI (samples/anatomical.nrrd, int16, cropped) and
from gen_dicom.py's CT series:

- `info --json`: kind nifti, dims, type, spacing = |pixdim|, the transform
  used and its matrix equal nibabel's header and affine, and the world
  transform maps the grid onto nibabel's affine (LPS by default, RAS with
  --ras, none with --grid-axes);
- every vertex of the mesh, mapped back by the inverse of nibabel's affine
  (after the LPS flip by default, directly with --ras), lies on an edge of
  the voxel grid (two index coordinates integers within 1e-4);
- a NIfTI written from a DICOM series (affine from the series' Image
  Position / Orientation, LPS -> RAS) gives the series' own mesh: the same
  triangles, positions within 1e-4 mm (axial and oblique);
- sform before qform before pixdim; scl_slope/scl_inter (type and values);
  .nii.gz, a .hdr/.img pair and NIfTI-2 give the .nii's mesh;
- a truncated .nii, a cut .nii.gz, a garbage header, a 4D file with two
  volumes, an RGB file and a missing file: exit 1, the file named, no output.
"""
import json
import os
import struct
import sys
import tempfile

import numpy as np
import nibabel as nib

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from clitest import check, failures, read_nrrd, read_ply_arrays, run as run_cli  # noqa: E402

CLI, SAMPLES, DICOM = sys.argv[1], os.path.abspath(sys.argv[2]), os.path.abspath(sys.argv[3])
LPS = np.diag([-1.0, -1.0, 1.0])


def run(args):
    return run_cli(CLI, args)


def info(path, *extra):
    r = run(["info", "--quiet", "--json", "-", path] + list(extra))
    check(r.returncode == 0, "info %s %s: exit %d %s" % (path, extra, r.returncode, r.stderr))
    return json.loads(r.stdout) if r.returncode == 0 else None


def extract(path, out, iso, *extra):
    r = run(["extract", "--quiet", "-o", out, "--iso", str(iso), path] + list(extra))
    check(r.returncode == 0, "extract %s %s: exit %d %s" % (path, extra, r.returncode, r.stderr))
    return read_ply_arrays(out) if r.returncode == 0 else (np.zeros((0, 6)), np.zeros((0, 3)))


def save(img, path, sform=None, scode=2, qform=None, qcode=1):
    """Saves with these forms and codes (an image without an affine of its
    own, so that nibabel's save keeps the header's forms as set)."""
    h = img.header.copy()
    h.set_sform(sform if sform is not None else img.affine, code=scode)
    h.set_qform(qform if qform is not None else img.affine, code=qcode)
    out = type(img)(np.asanyarray(img.dataobj), None, header=h)
    nib.save(out, path)
    return path


def rot(axis, deg):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    t = np.radians(deg)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * K @ K


def on_grid_edges(v, affine_ras, flip, what):
    """Every vertex, mapped back to (i, j, k), has two integer coordinates."""
    world = v[:, :3].astype(float) @ flip.T  # back to RAS
    ijk = (np.linalg.inv(affine_ras) @ np.c_[world, np.ones(len(world))].T).T[:, :3]
    near = np.abs(ijk - np.round(ijk)) < 1e-4
    bad = int((near.sum(axis=1) < 2).sum())
    check(len(v) > 100 and bad == 0, "%s: %d of %d vertices off the grid's edges (first %s)" %
          (what, bad, len(v), ijk[near.sum(axis=1) < 2][:1].tolist()))


def same_mesh(a, b, tol, what):
    (va, ta), (vb, tb) = a, b
    ok = va.shape == vb.shape and ta.shape == tb.shape and np.array_equal(ta, tb)
    err = float(np.abs(va[:, :3].astype(float) - vb[:, :3]).max()) if ok and len(va) else -1
    check(ok and len(va) > 100 and err <= tol,
          "%s: %s/%s vertices, %s/%s triangles, same triangles %s, max position difference %g (tol %g)" %
          (what, va.shape, vb.shape, ta.shape, tb.shape, ok and np.array_equal(ta, tb), err, tol))


def no_output(out, what):
    d = os.path.dirname(out)
    left = [f for f in os.listdir(d) if os.path.basename(out) in f]
    check(not left, "%s: output left behind: %s" % (what, left))


with tempfile.TemporaryDirectory() as tmp:
    p = lambda *n: os.path.join(tmp, *n)  # noqa: E731
    mri = read_nrrd(os.path.join(SAMPLES, "anatomical.nrrd"))  # [z, y, x]
    data = np.ascontiguousarray(mri.transpose(2, 1, 0))  # nibabel: [i, j, k], 33 x 41 x 25
    iso = float(np.percentile(data, 60)) + 0.5

    # an oblique sform with a mirror (i points left: det < 0, as most files)
    R = rot((1, 2, 0.5), 25) @ np.diag([-1.0, 1, 1])
    zooms = np.array([0.9, 1.1, 1.3])
    A = np.eye(4)
    A[:3, :3] = R @ np.diag(zooms)
    A[:3, 3] = [12.5, -30.25, 7.0]
    nii = save(nib.Nifti1Image(data, A), p("mri.nii"))
    img = nib.load(nii)
    Af = img.affine  # as stored (float32)

    # ---- (a) info: dims, type, spacing, transform ----
    for axes, flip, extra in (("patient", LPS, []), ("ras", np.eye(3), ["--ras"]), ("grid", None, ["--grid-axes"])):
        j = info(nii, *extra)
        if not j:
            continue
        n = j.get("nifti") or {}
        check(j["kind"] == "nifti" and j["format"] == "nifti1", "kind/format %s %s" % (j["kind"], j["format"]))
        check(j["dims"] == list(data.shape), "dims %s != %s" % (j["dims"], data.shape))
        check(j["type"] == "i16", "type %s" % j["type"])
        check(np.allclose(j["spacing"], img.header.get_zooms()[:3], rtol=0, atol=1e-6),
              "spacing %s != %s" % (j["spacing"], img.header.get_zooms()))
        check(n.get("transform") == "sform" and n.get("sform_code") == 2 and n.get("axes") == axes,
              "nifti %s" % n)
        check(np.allclose(np.reshape(n.get("file_affine", [0] * 12), (3, 4)), Af[:3], rtol=0, atol=1e-6),
              "file_affine %s != nibabel's %s" % (n.get("file_affine"), Af[:3].tolist()))
        W = np.reshape(j["world_transform"], (3, 4)) if j["world_transform"] else np.c_[np.eye(3), np.zeros(3)]
        sp, org = np.array(j["spacing"]), np.array(j["origin"])
        ijk = np.array([[0, 0, 0], [data.shape[0] - 1, 3, 7], [5, data.shape[1] - 1, data.shape[2] - 1]], float)
        got = (W[:, :3] @ (org + ijk * sp).T).T + W[:, 3]
        if flip is None:
            check(j["world_transform"] is None, "--grid-axes: world transform %s" % j["world_transform"])
        else:
            want = (flip @ (Af[:3, :3] @ ijk.T + Af[:3, 3:4])).T
            check(np.allclose(got, want, rtol=0, atol=1e-6), "%s: grid -> world %s != nibabel's %s" %
                  (axes, got.tolist(), want.tolist()))

    # ---- (b) vertices on the grid's edges through nibabel's affine ----
    m_lps = extract(nii, p("mri.ply"), iso, "--in-memory")
    on_grid_edges(m_lps[0], Af, LPS, "mri.nii (LPS)")
    m_ras = extract(nii, p("mri_ras.ply"), iso, "--ras")
    on_grid_edges(m_ras[0], Af, np.eye(3), "mri.nii --ras")
    check(np.allclose(m_ras[0][:, :3], m_lps[0][:, :3] * [-1, -1, 1], rtol=0, atol=1e-4),
          "--ras is not the LPS mesh with x and y negated")
    # the winding stays outward through the mirror (det < 0): the closed
    # mesh's signed volume and its normals against its faces keep their sign
    def orientation(mesh):
        v, t = mesh
        a, b, c = (v[t[:, i], :3].astype(float) for i in range(3))
        vol6 = float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum())
        agree = float((np.einsum("ij,ij->i", np.cross(b - a, c - a), v[t[:, 0], 3:6]) > 0).mean())
        return np.sign(vol6), agree

    sg, ag = orientation(extract(nii, p("pad_grid.ply"), iso, "--pad", "--grid-axes"))
    sw, aw = orientation(extract(nii, p("pad_lps.ply"), iso, "--pad"))
    check(sg == sw and sg != 0 and min(ag, 1 - ag) < 0.2 and min(aw, 1 - aw) < 0.2 and (ag > 0.5) == (aw > 0.5),
          "orientation through the mirror: signed volume %g/%g, normals with the faces %g/%g" % (sg, sw, ag, aw))

    # ---- (d) the same volume as .nii.gz, .hdr/.img, NIfTI-2 ----
    gz = save(nib.Nifti1Image(data, A), p("mri.nii.gz"))
    same_mesh(m_lps, extract(gz, p("gz.ply"), iso), 0, ".nii.gz vs .nii")
    # streamed (isomend_io_read_slice, slice by slice, mapped as it goes): the same bytes
    for path in (nii, gz):
        r = run(["extract", "--quiet", "-o", p("probe.ply"), "--iso", str(iso), "--json", "-", path])
        e = json.loads(r.stdout) if r.returncode == 0 else {"memory_estimate": 0, "memory_streaming": 0}
        r = run(["extract", "--quiet", "-o", p("streamed.ply"), "--iso", str(iso), "--json", "-", path,
                 "--max-memory", str((e["memory_estimate"] + e["memory_streaming"]) // 2)])
        check(r.returncode == 0 and json.loads(r.stdout)["streamed"] and
              open(p("streamed.ply"), "rb").read() == open(p("mri.ply"), "rb").read(),
              "%s: the streamed mesh differs from the in-memory one: %s" % (path, r.stderr))
    pair = save(nib.Nifti1Pair(data, A), p("pair.img"))
    check(os.path.exists(p("pair.hdr")), "nibabel wrote no pair.hdr")
    same_mesh(m_lps, extract(p("pair.hdr"), p("pair.ply"), iso), 0, ".hdr/.img vs .nii")
    same_mesh(m_lps, extract(pair, p("pair2.ply"), iso), 0, ".img (named) vs .nii")
    j = info(p("pair.hdr"))
    check(j and j["nifti"]["two_files"] and j["nifti"]["image_path"].endswith("pair.img"), "pair info %s" %
          (j or {}).get("nifti"))
    n2 = save(nib.Nifti2Image(data, A), p("mri2.nii"))
    j = info(n2)
    check(j and j["format"] == "nifti2" and j["nifti"]["version"] == 2, "NIfTI-2 format %s" % (j or {}).get("format"))
    same_mesh(m_lps, extract(n2, p("n2.ply"), iso), 1e-4, "NIfTI-2 vs NIfTI-1 (float32 affine)")
    on_grid_edges(read_ply_arrays(p("n2.ply"))[0], nib.load(n2).affine, LPS, "NIfTI-2")

    # ANALYZE 7.5 (.hdr/.img, no orientation): pixdim scaling, "method 1"
    nib.save(nib.AnalyzeImage(data, np.diag(list(zooms) + [1.0])), p("analyze.img"))
    j = info(p("analyze.hdr"))
    check(j and j["format"] == "analyze" and j["nifti"]["version"] == 0 and j["nifti"]["transform"] == "pixdim" and
          np.allclose(j["spacing"], zooms, atol=1e-6), "ANALYZE: %s" % ((j or {}).get("nifti"),))
    on_grid_edges(extract(p("analyze.hdr"), p("analyze.ply"), iso)[0], np.diag(list(zooms) + [1.0]), LPS, "ANALYZE")

    # ---- (d) sform before qform before pixdim ----
    Q = np.eye(4)
    Q[:3, :3] = rot((0, 0, 1), 90) @ np.diag(zooms)
    Q[:3, 3] = [-3, 4, 5]
    both = save(nib.Nifti1Image(data, A), p("both.nii"), sform=A, scode=1, qform=Q, qcode=1)
    only_q = save(nib.Nifti1Image(data, A), p("only_q.nii"), sform=A, scode=0, qform=Q, qcode=1)
    neither = save(nib.Nifti1Image(data, A), p("neither.nii"), sform=A, scode=0, qform=Q, qcode=0)
    for path, want, name in ((both, nib.load(both).header.get_sform(), "sform"),
                             (only_q, nib.load(only_q).header.get_qform(), "qform"),
                             (neither, np.diag(list(zooms) + [1.0]), "pixdim")):
        j = info(path)
        if not j:
            continue
        check(j["nifti"]["transform"] == name, "%s: transform %s, not %s" % (path, j["nifti"]["transform"], name))
        check(np.allclose(np.reshape(j["nifti"]["file_affine"], (3, 4)), want[:3], rtol=0, atol=1e-5),
              "%s: file_affine %s != %s" % (name, j["nifti"]["file_affine"], want[:3].tolist()))
        on_grid_edges(extract(path, p(name + ".ply"), iso)[0], want, LPS, "precedence: " + name)
    j = info(neither)
    check(j and j["world_transform"] == [-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 0] and np.allclose(j["origin"], 0),
          "pixdim only: a scaled grid at 0, RAS -> LPS (world transform %s)" % (j or {}).get("world_transform"))
    j = info(neither, "--ras")
    check(j and j["world_transform"] is None and np.allclose(j["origin"], 0),
          "pixdim only, --ras: the scaled grid at 0 (world transform %s)" % (j or {}).get("world_transform"))

    # ---- (d) scl_slope / scl_inter ----
    def scaled(dt, arr, slope, inter, name):
        """The stored samples as given, then scl_slope / scl_inter written
        into the header (bytes 112..119 of a NIfTI-1 header): nibabel would
        choose its own scaling for an array it is given."""
        stored = arr.astype(dt)
        path = save(nib.Nifti1Image(stored, A), p(name))
        with open(path, "r+b") as f:
            f.seek(112)
            f.write(struct.pack("<ff", slope, inter))
        back = nib.load(path)
        check(back.dataobj.slope == slope and back.dataobj.inter == inter and
              np.array_equal(back.dataobj.get_unscaled(), stored), "%s: not written as meant" % name)
        return path, stored.astype(float) * slope + inter

    u8 = (data.astype(float) - data.min()) / (data.max() - data.min()) * 255
    for dt, arr, slope, inter, want_type in (("<i2", data, 2.0, -1024.0, "i32"), ("u1", u8, 2.0, -1024.0, "i16"),
                                             ("u1", u8, 0.5, 3.0, "f32"), ("<u2", data - data.min(), 1.0, 0.0, "u16"),
                                             ("<f8", data, 2.0, -1024.0, "f64")):
        path, want = scaled(dt, arr, slope, inter, "scl_%s_%g_%g.nii" % (dt.strip("<"), slope, inter))
        j = info(path)
        if not j:
            continue
        check(j["type"] == want_type, "%s: type %s, want %s" % (path, j["type"], want_type))
        check(abs(j["min"] - want.min()) < 1e-4 and abs(j["max"] - want.max()) < 1e-4,
              "%s: range %g..%g, want %g..%g" % (path, j["min"], j["max"], want.min(), want.max()))
        check(j["nifti"]["scaled"] == ((slope, inter) != (1.0, 0.0)), "%s: scaled %s" % (path, j["nifti"]["scaled"]))
    # the scaled CT-like file meshes like its values: iso on HU = iso on stored
    path, want = scaled("<i2", data, 2.0, -1024.0, "scl_mesh.nii")
    same_mesh(m_lps, extract(path, p("scl.ply"), 2 * iso - 1024), 2e-4, "scaled (2, -1024) at 2 iso - 1024 vs unscaled")

    # ---- (c) a NIfTI of a DICOM series gives the series' mesh ----
    cases = json.load(open(os.path.join(DICOM, "cases.json")))
    for name in ("ct_folder", "ct_oblique", "ct_feet_first"):
        c = cases.get(name)
        check(c is not None and c["ok"], "no DICOM case %s in %s" % (name, DICOM))
        if not c:
            continue
        dims = c["dims"]
        v = np.fromfile(c["expected"], {"i16": "<i2", "u16": "<u2", "i32": "<i4"}[c["type"]])
        v = v.reshape(dims[::-1]).transpose(2, 1, 0)  # [x, y, z] = [i, j, k]
        Rs = np.array(c["affine"])[:, :3]  # [row | column | normal]
        lps = np.eye(4)
        lps[:3, :3] = Rs @ np.diag(c["spacing"])
        lps[:3, 3] = c["p0"]
        ras = np.diag([-1.0, -1, 1, 1]) @ lps
        for cls, suffix, tol in ((nib.Nifti1Image, ".nii", 1e-4), (nib.Nifti2Image, "_2.nii", 1e-5)):
            path = save(cls(np.ascontiguousarray(v), ras), p(name + suffix), scode=1, qcode=1)
            dm = extract(c["sources"][0], p(name + "_dicom.ply"), 300)
            nm = extract(path, p(name + suffix + ".ply"), 300)
            same_mesh(dm, nm, tol, "%s: NIfTI%s of the series vs the series" % (name, suffix))

    # ---- (e) bad files: exit 1, the file named, nothing written ----
    def refused(path, substring, what, status=1):
        out = p("bad.ply")
        r = run(["extract", "--quiet", "-o", out, "--iso", "1", path])
        line = r.stderr.strip().splitlines()[0] if r.stderr.strip() else ""
        check(r.returncode == status and line.startswith("isomend: ") and os.path.basename(path) in line and
              substring in line, "%s: exit %d, message %r (want %r)" % (what, r.returncode, r.stderr, substring))
        no_output(out, what)
        r = run(["info", "--quiet", path])
        check(r.returncode == status, "info %s: exit %d" % (what, r.returncode))

    raw = open(nii, "rb").read()
    open(p("truncated.nii"), "wb").write(raw[:len(raw) // 2])
    refused(p("truncated.nii"), "truncated", "truncated .nii")
    gzraw = open(gz, "rb").read()
    open(p("cut.nii.gz"), "wb").write(gzraw[:len(gzraw) // 2])
    refused(p("cut.nii.gz"), "truncated or corrupt", "cut .nii.gz")
    open(p("garbage.nii"), "wb").write(bytes(range(256)) * 8)
    refused(p("garbage.nii"), "not a NIfTI", "garbage header")
    four = np.stack([data, data], axis=-1)
    refused(save(nib.Nifti1Image(four, A), p("two_volumes.nii")), "2 volumes", "4D with 2 volumes")
    rgb = np.zeros(data.shape, dtype=[("R", "u1"), ("G", "u1"), ("B", "u1")])
    refused(save(nib.Nifti1Image(rgb, A), p("rgb.nii")), "RGB", "RGB")
    refused(p("missing.nii.gz"), "not found", "missing file")
    os.remove(p("pair.img"))
    refused(p("pair.hdr"), "missing", ".hdr without its .img")
    # a 4D file with one volume is a 3D volume
    one = save(nib.Nifti1Image(data[..., None], A), p("one_volume.nii"))
    same_mesh(m_lps, extract(one, p("one.ply"), iso), 0, "4D with one volume vs 3D")
    # --series does not apply; --ras does not apply to a DICOM series
    r = run(["info", nii, "--series", "1"])
    check(r.returncode == 2, "--series on NIfTI: exit %d %s" % (r.returncode, r.stderr))
    r = run(["info", cases["ct_folder"]["sources"][0], "--ras"])
    check(r.returncode == 2 and "NIfTI" in r.stderr, "--ras on DICOM: exit %d %s" % (r.returncode, r.stderr))

print("%d failures" % len(failures))
sys.exit(1 if failures else 0)
