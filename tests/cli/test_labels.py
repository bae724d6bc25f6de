"""isomend extract SOURCE --labels: label maps on the command line.

Label maps written here (NRRD by hand, NIfTI with nibabel): two touching
boxes, a one-voxel checkerboard of two labels (every face ambiguous), nested
spheres, 200 Voronoi cells, every NRRD integer type and uint32 through NIfTI.
Asserted:
  - every label's padded DMC surface closed: the JSON check, `isomend check`
    and VTK's vtkFeatureEdges (no boundary, no non-manifold edge);
  - per label, the triangles of vtkDiscreteFlyingEdges3D (VTK 9.1, all
    labels in one call) equal isomend's MC triangles exactly, and its DMC
    triangles less the mending quadrilaterals' (JSON triangles_by_origin);
    the vertex positions are VTK's (edge midpoints);
  - neighbours share their boundary: every midpoint of a grid edge between
    labels A and B is a vertex of A's and of B's file;
  - one pass == per-label extraction: a label's file is byte for byte the
    file `isomend extract` writes for its indicator (u8 0/1, --iso 0.5);
  - the same bytes at 1 and 2 threads;
  - -o FILE.ply: per-face label and colour; -o FILE.obj: a group a label,
    colours in FILE.mtl; names and colours from a .seg.nrrd, a 3D Slicer /
    FreeSurfer table and an ITK-SNAP label description;
  - bad input refused with a message naming the parameter, non-zero exit,
    no output: non-integer samples, a label not present, an unreadable or
    malformed table, STL for all labels, options that do not apply.
"""
import argparse
import json
import os
import shutil
import struct
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from clitest import check, read_ply_arrays, run as run_cli, same_file, summary  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--isomend", required=True)
ap.add_argument("--work", required=True)
ap.add_argument("--libisomend", help="the core library: its MC table's triangle counts")
ap.add_argument("--no-peers", action="store_true", help="skip VTK and nibabel")
args = ap.parse_args()
W = args.work
shutil.rmtree(W, ignore_errors=True)
os.makedirs(W)

NRRD_TYPE = {np.uint8: "uint8", np.int8: "int8", np.uint16: "uint16", np.int16: "int16",
             np.int32: "int32", np.float32: "float", np.float64: "double"}
SPACING = (0.5, 1.25, 2.0)
ORIGIN = (-3.0, 0.0, 7.5)


def run(a):
    return run_cli(args.isomend, a)


def write_nrrd(path, vol, extra=""):
    """vol[z, y, x] as an attached raw NRRD with SPACING and ORIGIN."""
    hdr = (f"NRRD0004\ntype: {NRRD_TYPE[vol.dtype.type]}\ndimension: 3\n"
           f"sizes: {vol.shape[2]} {vol.shape[1]} {vol.shape[0]}\nencoding: raw\nendian: little\n"
           f"space: right-anterior-superior\n"
           f"space directions: ({SPACING[0]},0,0) (0,{SPACING[1]},0) (0,0,{SPACING[2]})\n"
           f"space origin: ({ORIGIN[0]},{ORIGIN[1]},{ORIGIN[2]})\n{extra}\n")
    with open(path, "wb") as f:
        f.write(hdr.encode() + np.ascontiguousarray(vol).astype(vol.dtype.newbyteorder("<")).tobytes())


def touching():
    v = np.zeros((12, 11, 14), np.uint8)
    v[2:9, 2:9, 1:6] = 3
    v[2:9, 2:9, 6:12] = 7
    v[5, 5, 6] = 3
    return v


def checkerboard():
    z, y, x = np.indices((7, 8, 9))
    return np.where((x + y + z) % 2 == 1, 1, 2).astype(np.uint8)


def nested():
    z, y, x = np.indices((15, 16, 17)).astype(float)
    r = np.sqrt((x - 8.2) ** 2 + (y - 7.6) ** 2 + (z - 7.1) ** 2)
    return np.select([r < 3, r < 5.2, r < 7], [5, 4, 1], 0).astype(np.uint8)


def voronoi(cells, shape, seed=7):
    rng = np.random.default_rng(seed)
    pts = rng.random((cells, 3)) * np.array(shape)
    idx = np.indices(shape).reshape(3, -1).T.astype(np.float32)
    best = np.zeros(len(idx), np.int64)
    bd = np.full(len(idx), np.inf)
    for c in range(cells):
        d = ((idx - pts[c]) ** 2).sum(1)
        better = d < bd
        bd[better] = d[better]
        best[better] = c
    return (best + 1).reshape(shape)


def extract_json(src, out, *extra):
    r = run(["extract", src, "-o", out, "--json", "-", "--quiet", *extra])
    check(r.returncode == 0, f"{src} -> {out} {extra}: exit {r.returncode} {r.stderr}")
    return json.loads(r.stdout) if r.returncode == 0 else None


def positions(path):
    v, t = read_ply_arrays(path)
    return v[:, :3], t


def key_set(p):
    return set(map(tuple, np.round(np.asarray(p, np.float64), 4)))


def midpoints(vol, A, B, pad=1):
    """World positions of the midpoints of grid edges between A and B."""
    out = []
    for axis in range(3):  # numpy axis 2 = x
        a = np.moveaxis(vol, 2 - axis, 0)
        m = ((a[:-1] == A) & (a[1:] == B)) | ((a[:-1] == B) & (a[1:] == A))
        idx = np.argwhere(m).astype(np.float64)
        idx = np.moveaxis(idx.reshape(-1, 3), 0, 0)
        zyx = np.empty_like(idx)
        # back to (z, y, x) index order with the half step on the moved axis
        order = [2 - axis] + [d for d in range(3) if d != 2 - axis]
        for src_col, dst_axis in enumerate(order):
            zyx[:, dst_axis] = idx[:, src_col]
        zyx[:, 2 - axis] += 0.5
        xyz = zyx[:, ::-1]
        out.append(np.array(ORIGIN) + xyz * np.array(SPACING))
    return np.concatenate(out)


def vtk_counts(vol, labels, pad_value):
    """Per label: triangles and vertex positions of vtkDiscreteFlyingEdges3D
    on the padded volume (all labels in one call)."""
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy
    p = np.pad(vol.astype(np.int32), 1, constant_values=pad_value)
    img = vtk.vtkImageData()
    img.SetDimensions(p.shape[2], p.shape[1], p.shape[0])
    img.SetSpacing(*SPACING)
    img.SetOrigin(*(o - s for o, s in zip(ORIGIN, SPACING)))
    img.GetPointData().SetScalars(numpy_to_vtk(p.ravel(), deep=True))
    fe = vtk.vtkDiscreteFlyingEdges3D()
    fe.SetInputData(img)
    for i, L in enumerate(labels):
        fe.SetValue(i, float(L))
    fe.ComputeScalarsOn()
    fe.Update()
    out = fe.GetOutput()
    pts = vtk_to_numpy(out.GetPoints().GetData()) if out.GetNumberOfPoints() else np.zeros((0, 3))
    sc = vtk_to_numpy(out.GetPointData().GetScalars()) if out.GetNumberOfPoints() else np.zeros(0)
    cells = vtk_to_numpy(out.GetPolys().GetConnectivityArray()).reshape(-1, 3) \
        if out.GetNumberOfCells() else np.zeros((0, 3), np.int64)
    res = {}
    for L in labels:
        mine = cells[sc[cells[:, 0]] == L]
        res[L] = (len(mine), key_set(pts[np.unique(mine)]))
    return res


def table_delta():
    """Per configuration: vtkDiscreteFlyingEdges3D's triangles in one cube
    minus isomend's MC table's (isomend_case_triangles).  They differ on 44
    configurations, the inverted (5+ corners) cases 3, 6 and 7: VTK's table
    separates the label's corners on their ambiguous faces as in the
    uninverted cases, isomend's table (generated with inversion) joins them."""
    import ctypes
    import vtk
    from vtk.util.numpy_support import numpy_to_vtk
    lib = ctypes.CDLL(args.libisomend)
    lib.isomend_case_triangles.argtypes = [ctypes.c_uint, ctypes.c_void_p]
    delta = np.zeros(256, np.int64)
    for c in range(256):
        v = np.array([(c >> k) & 1 for k in range(8)], np.int32).reshape(2, 2, 2)
        img = vtk.vtkImageData()
        img.SetDimensions(2, 2, 2)
        img.GetPointData().SetScalars(numpy_to_vtk(v.ravel(), deep=True))
        fe = vtk.vtkDiscreteFlyingEdges3D()
        fe.SetInputData(img)
        fe.SetValue(0, 1.0)
        fe.Update()
        delta[c] = fe.GetOutput().GetNumberOfCells() - lib.isomend_case_triangles(c, None)
    return delta


def config_delta(vol, L, delta):
    """The triangles VTK's table gives label L beyond isomend's MC table."""
    p = np.pad(vol == L, 1).astype(np.int64)
    cfg = (p[:-1, :-1, :-1] | p[:-1, :-1, 1:] << 1 | p[:-1, 1:, :-1] << 2 | p[:-1, 1:, 1:] << 3 |
           p[1:, :-1, :-1] << 4 | p[1:, :-1, 1:] << 5 | p[1:, 1:, :-1] << 6 | p[1:, 1:, 1:] << 7)
    return int(delta[cfg].sum())


def vtk_closed(path):
    from vtkcheck import feature_edges, read_poly
    return feature_edges(read_poly(path))


def no_output(paths, what):
    for p in paths:
        check(not os.path.exists(p), f"{what}: {p} exists after a failure")


# ------------------------------------------------------------------ volumes
DELTA = table_delta() if not args.no_peers else None
check(DELTA is None or (np.count_nonzero(DELTA) == 44 and DELTA.min() == 0),
      "VTK's table differs from isomend's on other configurations than the 44 known")
vtk_stats = {"labels": 0, "equal": 0, "dmc_equal": 0}
cases = [("touching", touching()), ("checkerboard", checkerboard()), ("nested", nested()),
         ("voronoi200", voronoi(200, (26, 24, 28)).astype(np.uint8))]
for name, vol in cases:
    src = os.path.join(W, name + ".nrrd")
    write_nrrd(src, vol)
    d = os.path.join(W, name) + "/"
    j = extract_json(src, d, "--labels", "all", "--pad", "--threads", "2")
    jm = extract_json(src, os.path.join(W, name + "_mc") + "/", "--labels", "all", "--pad",
                      "--method", "mc")
    if not j or not jm:
        continue
    labels = [e["value"] for e in j["labels"]]
    if name == "checkerboard":  # every voxel its own octahedron, for both labels
        for e in j["labels"]:
            check(e["triangles"] == 8 * e["voxels"] and e["vertices"] == 6 * e["voxels"] and
                  e["components"] == e["voxels"], f"checkerboard label {e['value']}: {e}")
    check(labels == sorted(int(x) for x in np.unique(vol) if x != 0), f"{name}: labels {labels}")
    vox = {int(x): int((vol == x).sum()) for x in labels}
    peers = None
    if not args.no_peers:
        peers = vtk_counts(vol, labels, 0)
    for e, m in zip(j["labels"], jm["labels"]):
        L = e["value"]
        what = f"{name} label {L}"
        check(e["voxels"] == vox[L], f"{what}: voxels {e['voxels']} != {vox[L]}")
        c = e["check"]
        check(c["continuous"] and c["holes"] == 0 and c["border_edges"] == 0 and
              c["nonmanifold_edges"] == 0 and c["misoriented_edges"] == 0,
              f"{what}: not closed {c}")
        check(e["components"] == c["components"] and e["components"] >= 1, f"{what}: components")
        r = run(["check", e["file"]])
        check(r.returncode == 0, f"{what}: isomend check {e['file']}: {r.stdout} {r.stderr}")
        if peers:
            check(vtk_closed(e["file"]) == (0, 0), f"{what}: vtkFeatureEdges {vtk_closed(e['file'])}")
            vt, vpos = peers[L]
            mend = e["triangles_by_origin"]["mend"]
            extra = config_delta(vol, L, DELTA)
            check(m["triangles"] + extra == vt,
                  f"{what}: MC {m['triangles']} + {extra} (VTK's table) triangles, "
                  f"vtkDiscreteFlyingEdges3D {vt}")
            check(m["triangles"] == e["triangles"] - mend, f"{what}: DMC less mending is not MC")
            vtk_stats["labels"] += 1
            vtk_stats["equal"] += m["triangles"] == vt
            vtk_stats["dmc_equal"] += e["triangles"] == vt
            check(key_set(positions(e["file"])[0]) == vpos, f"{what}: vertex positions not VTK's")
        if name == "voronoi200" and L > 12:
            continue  # the byte comparisons below on a dozen labels are enough
        # one pass == the indicator's own extraction, byte for byte
        ind = os.path.join(W, f"{name}_ind{L}.nrrd")
        write_nrrd(ind, (vol == L).astype(np.uint8))
        ref = os.path.join(W, f"{name}_ind{L}.ply")
        r = run(["extract", ind, "--iso", "0.5", "--pad", "--quiet", "-o", ref])
        check(r.returncode == 0 and same_file(ref, e["file"]),
              f"{what}: not the bytes of isomend extract on the indicator")
    # neighbours share their boundary's vertices
    files = {e["value"]: e["file"] for e in j["labels"]}
    pairs = [(labels[a], labels[b]) for a in range(min(4, len(labels)))
             for b in range(a + 1, min(6, len(labels)))]
    shared = 0
    for A, B in pairs:
        mp = key_set(midpoints(vol, A, B))
        if not mp:
            continue
        shared += 1
        pa, pb = key_set(positions(files[A])[0]), key_set(positions(files[B])[0])
        check(mp <= pa and mp <= pb, f"{name}: labels {A} and {B} do not share their boundary")
    check(shared > 0, f"{name}: no touching pair tested")
    # streamed (--stream: a slice at a time, the labels listed by a first pass): the same bytes
    ds = os.path.join(W, name + "_stream") + "/"
    js = extract_json(src, ds, "--labels", "all", "--pad", "--stream")
    if js:
        check([e["triangles"] for e in js["labels"]] == [e["triangles"] for e in j["labels"]],
              f"{name}: streamed triangles differ")
        for e, es in zip(j["labels"], js["labels"]):
            check(same_file(e["file"], es["file"]), f"{name}: --stream differs ({e['value']})")
        check(js["streamed"] and not j["streamed"], f"{name}: 'streamed' {js['streamed']}, {j['streamed']}")
    # a map over half of --max-memory is read a slice at a time by itself: the same bytes
    dm = os.path.join(W, name + "_maxmem") + "/"
    jx = extract_json(src, dm, "--labels", "all", "--pad", "--max-memory", str(vol.nbytes // 2 - 1))
    if jx:
        check(jx["streamed"], f"{name}: a map over half of --max-memory was not streamed")
        for e, em in zip(j["labels"], jx["labels"]):
            check(same_file(e["file"], em["file"]), f"{name}: under --max-memory differs ({e['value']})")
    # the same bytes at 1 thread
    d1 = os.path.join(W, name + "_t1") + "/"
    j1 = extract_json(src, d1, "--labels", "all", "--pad", "--threads", "1")
    if j1:
        for e, e1 in zip(j["labels"], j1["labels"]):
            check(same_file(e["file"], e1["file"]), f"{name}: threads 1 and 2 differ ({e['value']})")

if DELTA is not None:
    print(f"vtkDiscreteFlyingEdges3D: {vtk_stats['labels']} labels; MC's count equal on "
          f"{vtk_stats['equal']}, DMC's on {vtk_stats['dmc_equal']}; every difference is VTK's "
          f"table on the inverted cases 3, 6, 7", flush=True)

# ------------------------------------------------- every integer type, NIfTI
base = nested()
ref = extract_json(os.path.join(W, "nested.nrrd"), os.path.join(W, "types_ref.ply"),
                   "--labels", "1,4,5", "--pad")
for dt, off in [(np.int8, -100), (np.uint16, 60000), (np.int16, -30000), (np.int32, -2000000000)]:
    v = np.where(base > 0, base.astype(np.int64) + off, 0).astype(dt)
    src = os.path.join(W, f"type_{np.dtype(dt).name}.nrrd")
    write_nrrd(src, v)
    j = extract_json(src, os.path.join(W, f"type_{np.dtype(dt).name}.ply"), "--labels",
                     ",".join(str(x + off) for x in (1, 4, 5)), "--pad")
    if j and ref:
        check([e["triangles"] for e in j["labels"]] == [e["triangles"] for e in ref["labels"]],
              f"type {np.dtype(dt).name}: triangles differ from u8")
        check(j["type"] == {"int8": "i8", "uint16": "u16", "int16": "i16", "int32": "i32"}[
            np.dtype(dt).name], f"type {np.dtype(dt).name}: JSON type {j['type']}")
if not args.no_peers:
    import nibabel as nib
    for dt, off in [(np.int16, 0), (np.uint32, 4000000000)]:
        v = np.where(base > 0, base.astype(np.int64) + off, 0).astype(dt)
        path = os.path.join(W, f"labels_{np.dtype(dt).name}.nii.gz")
        nib.save(nib.Nifti1Image(np.ascontiguousarray(v.transpose(2, 1, 0)),
                                 np.diag([SPACING[0], SPACING[1], SPACING[2], 1.0])), path)
        d = os.path.join(W, f"nifti_{np.dtype(dt).name}") + "/"
        j = extract_json(path, d, "--labels", "all", "--pad")
        if np.dtype(dt) == np.int16:  # the importer's slices streamed: the same files
            js = extract_json(path, d[:-1] + "_stream/", "--labels", "all", "--pad", "--stream")
            for e, es in zip(j["labels"] if j else [], js["labels"] if js else []):
                check(same_file(e["file"], es["file"]), f"NIfTI --stream: label {e['value']}")
        if j and ref:
            check([e["value"] for e in j["labels"]] == [x + off for x in (1, 4, 5)],
                  f"NIfTI {np.dtype(dt).name}: labels {[e['value'] for e in j['labels']]}")
            check([e["triangles"] for e in j["labels"]] == [e["triangles"] for e in ref["labels"]],
                  f"NIfTI {np.dtype(dt).name}: triangles differ from the NRRD's")
            for e in j["labels"]:
                check(e["check"]["continuous"] and e["check"]["border_edges"] == 0,
                      f"NIfTI {np.dtype(dt).name} label {e['value']}: not closed")
                if not args.no_peers:
                    check(vtk_closed(e["file"]) == (0, 0), f"NIfTI label {e['value']}: VTK edges")
    # a radiological NIfTI (det < 0, as most are): placed by its affine in patient LPS, each
    # label still closed (VTK on the written files) and outward (positive signed volume)
    path = os.path.join(W, "labels_mirror.nii.gz")
    aff = np.array([[-0.8, 0, 0, 10], [0, 0.9, 0, -5], [0, 0, 1.5, 3], [0, 0, 0, 1.0]])
    nib.save(nib.Nifti1Image(np.ascontiguousarray(base.transpose(2, 1, 0)), aff), path)
    for flags in ([], ["--ras"]):
        d = os.path.join(W, "nifti_mirror" + "".join(flags)) + "/"
        j = extract_json(path, d, "--labels", "all", "--pad", *flags)
        for e in j["labels"] if j else []:
            p, t = positions(e["file"])
            q = p.astype(np.float64)[t.astype(np.int64)]
            vol = np.einsum("ij,ij->i", q[:, 0], np.cross(q[:, 1], q[:, 2])).sum() / 6.0
            check(vol > 0, f"mirrored NIfTI {flags} label {e['value']}: signed volume {vol}")
            if not args.no_peers:
                check(vtk_closed(e["file"]) == (0, 0), f"mirrored NIfTI label {e['value']}: VTK")
    # float samples that are not whole numbers: refused, nothing written
    path = os.path.join(W, "float.nii.gz")
    nib.save(nib.Nifti1Image(base.astype(np.float32).transpose(2, 1, 0) * 0.5, np.eye(4)), path)
    out = os.path.join(W, "float_out") + "/"
    r = run(["extract", path, "--labels", "all", "-o", out])
    check(r.returncode != 0 and "--labels" in r.stderr and "integer" in r.stderr,
          f"float label map: exit {r.returncode}, {r.stderr}")
    no_output([out], "float label map")

# -------------------------------------------- one file: PLY faces, OBJ + MTL
seg = os.path.join(W, "liver.seg.nrrd")
write_nrrd(seg, touching(), "Segment0_Name:=liver right\nSegment0_Color:=1 0.5 0\n"
           "Segment0_LabelValue:=3\nSegment1_Name:=kidney\nSegment1_Color:=0 0 1\n"
           "Segment1_LabelValue:=7\n")
j = extract_json(seg, os.path.join(W, "seg.ply"), "--labels", "all", "--pad")
if j:
    check(j["names_from"] == "seg.nrrd" and [e["name"] for e in j["labels"]] ==
          ["liver_right", "kidney"], f"seg.nrrd names {[e['name'] for e in j['labels']]}")
    check([e["color"] for e in j["labels"]] == [[255, 128, 0], [0, 0, 255]],
          f"seg.nrrd colours {[e['color'] for e in j['labels']]}")
    data = open(os.path.join(W, "seg.ply"), "rb").read()
    end = data.index(b"end_header\n") + 11
    hdr = data[:end].decode()
    nv = int(hdr.split("element vertex ")[1].split()[0])
    nf = int(hdr.split("element face ")[1].split()[0])
    check("property uint label" in hdr and "property uchar red" in hdr, "PLY face properties")
    check(nf == sum(e["triangles"] for e in j["labels"]), "PLY: face count")
    faces = np.frombuffer(data[end + nv * 24:], dtype=np.dtype(
        [("n", "u1"), ("v", "<u4", 3), ("label", "<u4"), ("rgb", "u1", 3)]), count=nf)
    for e in j["labels"]:
        sel = faces[faces["label"] == e["value"]]
        check(len(sel) == e["triangles"], f"PLY: label {e['value']} faces {len(sel)}")
        check((sel["rgb"] == e["color"]).all(), f"PLY: label {e['value']} colour")
    if not args.no_peers:
        check(vtk_closed(os.path.join(W, "seg.ply")) == (0, 0), "seg.ply: VTK feature edges")
j = extract_json(seg, os.path.join(W, "seg.obj"), "--labels", "7,3", "--pad")
if j:
    obj = open(os.path.join(W, "seg.obj")).read().splitlines()
    mtl = open(os.path.join(W, "seg.mtl")).read()
    check("mtllib seg.mtl" in obj, "OBJ: mtllib")
    groups = [x.split()[1] for x in obj if x.startswith("g ")]
    check(groups == ["kidney", "liver_right"], f"OBJ groups {groups}")
    check("newmtl kidney\nKd 0.000000 0.000000 1.000000" in mtl, "MTL colours")
    check(sum(x.startswith("f ") for x in obj) == sum(e["triangles"] for e in j["labels"]),
          "OBJ: faces")

# ------------------------------------------------------------ info --labels
r = run(["info", seg, "--labels", "all", "--json", "-", "--quiet"])
check(r.returncode == 0, f"info --labels: {r.stderr}")
if r.returncode == 0:
    ji = json.loads(r.stdout)
    tv = touching()
    want = [[int(x), int((tv == x).sum())] for x in np.unique(tv)]
    check([[e["value"], e["voxels"]] for e in ji["labels"]] == want,
          f"info --labels: {[[e['value'], e['voxels']] for e in ji['labels']]} != {want}")
    check([e["name"] for e in ji["labels"]] == ["label_0", "liver_right", "kidney"] and
          ji["labels"][1]["color"] == [255, 128, 0], f"info --labels names {ji['labels']}")

# ------------------------------------------------------------ colour tables
tables = {
    "slicer.ctbl": "# Color table file\n# 3 values\n0 Background 0 0 0 0\n3 Liver 220 100 80 255\n"
                   "7 Kidney_L 10 20 30 255\n",
    "FreeSurferColorLUT.txt": "#$Id: FreeSurferColorLUT.txt\n\n0   Unknown   0 0 0 0\n"
                              "3   Left-Cerebral-Cortex   205  62  78   0\n"
                              "7   Left-Cerebellum-White-Matter  220 248 164 0\n",
    "itksnap.txt": "# ITK-SnAP Label Description File\n"
                   "    0     0    0    0        0  0  0    \"Clear Label\"\n"
                   "    3   255    0    0        1  1  1    \"liver segment\"\n"
                   "    7     0  255    0        1  1  1    \"kidney\"\n",
}
expect = {"slicer.ctbl": (["Liver", "Kidney_L"], [[220, 100, 80], [10, 20, 30]]),
          "FreeSurferColorLUT.txt": (["Left-Cerebral-Cortex", "Left-Cerebellum-White-Matter"],
                                     [[205, 62, 78], [220, 248, 164]]),
          "itksnap.txt": (["liver_segment", "kidney"], [[255, 0, 0], [0, 255, 0]])}
for tname, text in tables.items():
    tp = os.path.join(W, tname)
    open(tp, "w").write(text)
    d = os.path.join(W, "table_" + tname.split(".")[0]) + "/"
    j = extract_json(seg, d, "--labels", "all", "--pad", "--label-table", tp, "--format", "stl")
    if j:
        names, colours = expect[tname]
        check([e["name"] for e in j["labels"]] == names, f"{tname}: names {[e['name'] for e in j['labels']]}")
        check([e["color"] for e in j["labels"]] == colours, f"{tname}: colours")
        check(sorted(os.listdir(d)) == sorted(n + ".stl" for n in names), f"{tname}: files {os.listdir(d)}")
        r = run(["check", os.path.join(d, names[0] + ".stl")])
        check(r.returncode == 0, f"{tname}: isomend check of the STL")

# -------------------------------------------------------------- bad input
def refused(argv, needle, outputs, what, status=None):
    r = run(argv)
    check(r.returncode != 0 and (status is None or r.returncode == status) and needle in r.stderr,
          f"{what}: exit {r.returncode}, stderr {r.stderr!r}")
    no_output(outputs, what)


src = os.path.join(W, "touching.nrrd")
out = os.path.join(W, "bad") + "/"
refused(["extract", src, "--labels", "3,9", "--pad", "-o", out], "--labels: label 9", [out],
        "label not present", 1)
refused(["extract", src, "--labels", "3,x", "-o", out], "--labels", [out], "bad label", 2)
refused(["extract", src, "--labels", "3,3", "-o", out], "twice", [out], "label twice", 2)
refused(["extract", src, "--labels", "all", "--label-table", os.path.join(W, "none.ctbl"),
         "-o", out], "--label-table", [out], "unreadable table", 1)
bad_table = os.path.join(W, "bad.ctbl")
open(bad_table, "w").write("3 Liver 220 100\n")
refused(["extract", src, "--labels", "all", "--label-table", bad_table, "-o", out],
        "--label-table", [out], "malformed table", 1)
refused(["extract", src, "--labels", "all", "-o", os.path.join(W, "bad.stl")], "STL",
        [os.path.join(W, "bad.stl")], "STL for all labels", 2)
refused(["extract", src, "--labels", "all", "--iso", "3", "-o", out], "--iso", [out], "--iso", 2)
refused(["extract", src, "--labels", "all", "--chunk-layers", "4", "-o", out], "--chunk-layers",
        [out], "--chunk-layers", 2)
refused(["extract", src, "--labels", "all", "--method", "mc33", "-o", out], "--method", [out],
        "mc33", 2)
refused(["extract", src, "--iso", "3", "--label-table", bad_table, "-o", os.path.join(W, "x.ply")],
        "--label-table", [os.path.join(W, "x.ply")], "table without --labels", 2)
refused(["extract", src, "--labels", "all", "--format", "stl", "-o", os.path.join(W, "y.ply")],
        "--format", [os.path.join(W, "y.ply")], "--format with a file", 2)
refused(["info", seg, "--labels", "3"], "--labels all", [], "info --labels 3", 2)
refused(["info", seg, "--label-table", bad_table], "--label-table", [], "info --label-table", 2)
deep = os.path.join(W, "no", "such", "folder") + "/"
refused(["extract", src, "--labels", "all", "-o", deep], "cannot create the folder", [deep],
        "folder in a missing folder", 1)
zero = os.path.join(W, "zero.nrrd")
write_nrrd(zero, np.zeros((4, 4, 4), np.uint8))
refused(["extract", zero, "--labels", "all", "-o", out], "no label", [out], "all background", 1)
fl = os.path.join(W, "float.nrrd")
write_nrrd(fl, nested().astype(np.float32) + 0.25)
refused(["extract", fl, "--labels", "all", "-o", out], "--labels", [out], "float NRRD", 1)
refused(["extract", fl, "--labels", "all", "--stream", "-o", out], "--stream", [out],
        "float NRRD streamed", 1)
# a float volume of whole numbers is a label map
write_nrrd(fl, nested().astype(np.float32))
j = extract_json(fl, os.path.join(W, "float_whole.ply"), "--labels", "1,4,5", "--pad")
if j and ref:
    check([e["triangles"] for e in j["labels"]] == [e["triangles"] for e in ref["labels"]],
          "whole-number float: triangles differ from u8")
sys.exit(summary())
