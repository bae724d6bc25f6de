"""isomend extract SOURCE --labels ... with --smooth, --decimate, --min-component: a
label map's surfaces smoothed and decimated together (isomend_meshes_smooth,
isomend_meshes_decimate), so that neighbours still meet, and cleaned a label at a time.

Label maps written here as raw u8: two touching boxes, three boxes meeting
along a line, a ball in a shell. For --smooth 10 and 30, asserted:
  - every label's file closed and oriented: the JSON check and `isomend
    check` (no hole, no once-used or 3+-used edge, nothing misoriented), the
    components and Euler characteristic of the unsmoothed run; with VTK
    (--vtk), vtkFeatureEdges finds no boundary and no non-manifold edge;
  - the triangles are the unsmoothed run's, the vertices moved;
  - neighbours still meet: every vertex two labels' files share without
    smoothing (the same position in both) is, in the smoothed files, at one
    position in both again (the same index's vertex), and it moved;
  - each label's volume (the JSON's smooth object, and recomputed from the
    file) within 1 % of the unsmoothed one at 10 iterations, 2 % at 30 (no
    volume is restored: the filter alone; the small ball loses 1.2 % at 30);
  - the same bytes twice;
  - --decimate 0.3 and --max-error 0.3 (alone and after --smooth 10): each
    label closed with its components and Euler characteristic (JSON check,
    VTK), every vertex two labels share before still in both files (the
    shared vertices are locked), fewer triangles in all;
  - --min-component a label at a time: an island of label 1 inside label 2
    goes from label 1's file and label 2's cavity around it from label 2's,
    both closed;
  - bad values (--decimate 0, --smooth 0, --min-component 0) refused (exit 2,
    no output).
"""
import argparse
import json
import os
import shutil
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from clitest import check, read_ply_arrays, run as run_clitest, same_file, summary  # noqa: E402


def run_cli(exe, args):
    p = run_clitest(exe, args)
    return p.returncode, p.stdout, p.stderr

ap = argparse.ArgumentParser()
ap.add_argument("--isomend", required=True)
ap.add_argument("--work", required=True)
ap.add_argument("--vtk", action="store_true", help="also judge the files with VTK")
a = ap.parse_args()
shutil.rmtree(a.work, ignore_errors=True)
os.makedirs(a.work)


def maps():
    t = np.zeros((18, 18, 24), np.uint8)  # [z, y, x]
    t[3:15, 3:15, 2:11] = 1
    t[3:15, 3:15, 11:22] = 2
    three = np.zeros((16, 22, 22), np.uint8)
    three[2:14, 2:20, 2:11] = 1
    three[2:14, 11:20, 2:11] = 2
    three[2:14, 2:20, 11:20] = 3
    z, y, x = np.mgrid[:24, :24, :24]
    r = np.sqrt((x - 11.5) ** 2 + (y - 11.5) ** 2 + (z - 11.5) ** 2)
    nested = np.where(r < 5.2, 4, np.where(r < 9.6, 9, 0)).astype(np.uint8)
    return [("touching", t), ("three", three), ("nested", nested)]


def volume(verts, tris):
    p = verts[:, :3].astype(np.float64)
    a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def extract(name, raw, shape, flags, out):
    rc, so, se = run_cli(a.isomend, ["extract", raw, "--raw", f"{shape[2]},{shape[1]},{shape[0]}:u8",
                                     "--labels", "all", "--pad", *flags, "-o", out, "--json", "-", "-q"])
    check(rc == 0, f"{name} {' '.join(flags)}: exit {rc}: {se.strip()}")
    return json.loads(so) if rc == 0 else None


for name, vol in maps():
    raw = os.path.join(a.work, f"{name}.raw")
    vol.tofile(raw)
    base_dir = os.path.join(a.work, f"{name}_raw") + "/"
    j0 = extract(name, raw, vol.shape, [], base_dir)
    if not j0:
        continue
    files0 = {l["value"]: read_ply_arrays(l["file"]) for l in j0["labels"]}
    vols0 = {v: volume(*files0[v]) for v in files0}
    # the vertices two labels share: (label p, index a, label q, index b)
    shared = []
    values = sorted(files0)
    for i, p in enumerate(values):
        key = {tuple(row): k for k, row in enumerate(files0[p][0][:, :3].tolist())}
        for q in values[i + 1:]:
            for k, row in enumerate(files0[q][0][:, :3].tolist()):
                if tuple(row) in key:
                    shared.append((p, key[tuple(row)], q, k))
    check(len(shared) > 0, f"{name}: no vertex shared by two labels before smoothing")
    for n in (10, 30):
        tag = f"{name} --smooth {n}"
        out_dir = os.path.join(a.work, f"{name}_s{n}") + "/"
        j = extract(tag, raw, vol.shape, ["--smooth", str(n)], out_dir)
        again = extract(tag, raw, vol.shape, ["--smooth", str(n)], os.path.join(a.work, f"{name}_s{n}b") + "/")
        if not j or not again:
            continue
        files = {}
        for l, l0, lb in zip(j["labels"], j0["labels"], again["labels"]):
            v = l["value"]
            c, c0 = l["check"], l0["check"]
            check(c["holes"] == 0 and c["nonmanifold_edges"] == 0 and c["misoriented_edges"] == 0
                  and c["border_edges"] == 0, f"{tag} label {v}: not closed: {c}")
            check(c["components"] == c0["components"] and c["euler"] == c0["euler"],
                  f"{tag} label {v}: topology changed: {c0} -> {c}")
            check(same_file(l["file"], lb["file"]), f"{tag} label {v}: two runs, different files")
            rc, so, se = run_cli(a.isomend, ["check", l["file"], "--json", "-"])
            cj = json.loads(so) if rc == 0 else {}
            cc = cj.get("check", {})
            check(rc == 0 and cc.get("holes") == 0 and cc.get("nonmanifold_edges") == 0 and
                  cc.get("misoriented_edges") == 0 and cc.get("border_edges") == 0 and
                  cc.get("components") == c0["components"] and cc.get("euler") == c0["euler"],
                  f"{tag} label {v}: isomend check: {rc} {cc}{se}")
            verts, tris = read_ply_arrays(l["file"])
            files[v] = (verts, tris)
            check(np.array_equal(tris, files0[v][1]), f"{tag} label {v}: triangles changed")
            moved = np.abs(verts[:, :3] - files0[v][0][:, :3]).max()
            check(moved > 0.01, f"{tag} label {v}: nothing moved ({moved})")
            sm = (l.get("postprocess") or {}).get("smooth") or {}
            check(sm.get("moved_vertices", 0) > 0, f"{tag} label {v}: {sm}")
            v1 = volume(verts, tris)
            limit = 0.01 if n <= 10 else 0.02  # no restoration: the filter alone
            check(abs(v1 - vols0[v]) < limit * abs(vols0[v]), f"{tag} label {v}: volume {vols0[v]} -> {v1}")
            check(abs(sm.get("volume_after", 0) - v1) < 1e-3 * abs(v1),
                  f"{tag} label {v}: reported volume {sm.get('volume_after')} for {v1}")
            if a.vtk:
                sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
                import vtkcheck
                fe = vtkcheck.feature_edges(vtkcheck.read_poly(l["file"]))
                check(fe == (0, 0), f"{tag} label {v}: VTK's boundary / non-manifold edges {fe}")
        if len(files) != len(files0):
            continue
        apart = [s for s in shared
                 if not np.array_equal(files[s[0]][0][s[1], :3], files[s[2]][0][s[3], :3])]
        check(not apart, f"{tag}: {len(apart)} of {len(shared)} shared vertices parted, e.g. {apart[:3]}")
        still = sum(np.array_equal(files[p][0][i, :3], files0[p][0][i, :3]) for p, i, _, _ in shared)
        check(still < len(shared), f"{tag}: no shared vertex moved")
        print(f"{tag}: {len(j['labels'])} labels closed, {len(shared)} shared vertices still shared, volumes "
              + ", ".join(f"{l['value']}: {100 * (l['postprocess']['smooth']['volume_after'] / l['postprocess']['smooth']['volume_before'] - 1):+.3f} %"
                          for l in j["labels"]))

    # --decimate (after --smooth 10 or alone): the shared vertices locked, so the
    # surfaces two labels share stay in both files; each label closed with its
    # components and Euler characteristic, fewer triangles where a label has a
    # surface against the background
    for flags in (["--decimate", "0.3"], ["--smooth", "10", "--decimate", "0.3"], ["--max-error", "0.3"]):
        tag = f"{name} {' '.join(flags)}"
        out_dir = os.path.join(a.work, f"{name}_d{len(flags)}{flags[-1]}") + "/"
        j = extract(tag, raw, vol.shape, flags, out_dir)
        if not j:
            continue
        pos = {}
        for l, l0 in zip(j["labels"], j0["labels"]):
            v = l["value"]
            c, c0 = l["check"], l0["check"]
            check(c["holes"] == 0 and c["nonmanifold_edges"] == 0 and c["misoriented_edges"] == 0
                  and c["border_edges"] == 0 and c["components"] == c0["components"]
                  and c["euler"] == c0["euler"], f"{tag} label {v}: {c0} -> {c}")
            if a.vtk:
                import vtkcheck
                fe = vtkcheck.feature_edges(vtkcheck.read_poly(l["file"]))
                check(fe == (0, 0), f"{tag} label {v}: VTK's boundary / non-manifold edges {fe}")
            verts, tris = read_ply_arrays(l["file"])
            pos[v] = {tuple(r) for r in verts[:, :3].tolist()}
            d = l["postprocess"]["decimate"]
            check(d["triangles_after"] == len(tris) and d["locked_vertices"] > 0, f"{tag} label {v}: {d}")
        # every vertex two labels share (after smoothing, if any) is in both files
        ref = j0 if "--smooth" not in flags else extract(tag + " (smoothed only)", raw, vol.shape,
                                                         ["--smooth", "10"], out_dir[:-1] + "_s/")
        if not ref:
            continue
        before = {l["value"]: read_ply_arrays(l["file"])[0][:, :3].tolist() for l in ref["labels"]}
        lost = 0
        for p_, i, q_, k in shared:
            pt = tuple(before[p_][i])
            check(pt == tuple(before[q_][k]), f"{tag}: shared vertex apart before decimating")
            lost += pt not in pos[p_] or pt not in pos[q_]
        check(lost == 0, f"{tag}: {lost} of {len(shared)} shared vertices gone from a label's file")
        total0 = sum(l["triangles"] for l in ref["labels"])
        total1 = sum(l["triangles"] for l in j["labels"])
        check(total1 < total0, f"{tag}: {total0} -> {total1} triangles")
        print(f"{tag}: {total0} -> {total1} triangles, closed, {len(shared)} shared vertices kept in both")

# --min-component a label at a time: an island of label 1 (8 voxels) inside
# label 2 goes from label 1's file, and label 2's cavity around it (the same
# small surface) from label 2's; both stay closed
isl = np.zeros((18, 18, 24), np.uint8)
isl[3:15, 3:15, 2:11] = 1
isl[3:15, 3:15, 11:22] = 2
isl[8:10, 8:10, 15:17] = 1  # an island of label 1 inside label 2
raw_isl = os.path.join(a.work, "island.raw")
isl.tofile(raw_isl)
j1 = extract("island", raw_isl, isl.shape, [], os.path.join(a.work, "island_raw") + "/")
j2 = extract("island --min-component 100", raw_isl, isl.shape, ["--min-component", "100"],
             os.path.join(a.work, "island_clean") + "/")
if j1 and j2:
    c1 = {l["value"]: l for l in j1["labels"]}
    c2 = {l["value"]: l for l in j2["labels"]}
    check(c1[1]["components"] == 2 and c2[1]["components"] == 1, f"island: label 1 {c1[1]['components']} -> {c2[1]['components']}")
    check(c2[1]["postprocess"]["clean"]["components_before"] == 2 and
          c2[1]["postprocess"]["clean"]["components_after"] == 1, f"island: {c2[1]['postprocess']['clean']}")
    # label 2's cavity around the island is the same small surface: it goes too
    check(c1[2]["components"] == 2 and c2[2]["components"] == 1,
          f"island: label 2 {c1[2]['components']} -> {c2[2]['components']} components")
    for l in j2["labels"]:
        c = l["check"]
        check(c["holes"] == 0 and c["nonmanifold_edges"] == 0 and c["border_edges"] == 0, f"island label {l['value']}: {c}")

# the steps that would part the neighbours are refused
raw = os.path.join(a.work, "touching.raw")
for flags in (["--decimate", "0"], ["--smooth", "0"], ["--min-component", "0"]):
    out = os.path.join(a.work, "refused") + "/"
    rc, so, se = run_cli(a.isomend, ["extract", raw, "--raw", "24,18,18:u8", "--labels", "all", "--pad",
                                     *flags, "-o", out])
    check(rc == 2 and flags[0] in se and not os.path.exists(out), f"{' '.join(flags)}: exit {rc}, {se.strip()}")
sys.exit(summary())
