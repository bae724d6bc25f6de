#!/usr/bin/env python3
"""`isomend info` and `isomend extract` on the DICOM series of gen_dicom.py.

Usage: test_dicom_cli.py ISOMEND_CLI DICOM_DIR

- every defect: exit status 1, one message naming a file of the series and
  the reason, no output file (nor a temporary one) left behind;
- every good series: `info --json` says kind "dicom" with the dimensions,
  type, spacing, origin and world transform that were meant;
- the mesh streamed (--max-memory) equals the in-memory one byte for byte,
  also mapped to patient space (oblique, feet first, mirrored);
- the mesh from a DICOM series equals the mesh from the same volume given as
  raw with the same spacing and origin: byte for byte for an axial series and
  for --grid-axes; for a turned series, the raw mesh mapped by the series'
  transform (numpy) within float rounding, the same triangles;
- a CT folder becomes a closed, outward bone mesh in millimetres with one
  command (the bone level by default), also oblique and feet first;
- several series: `info` lists them (exit 0), `extract` refuses (exit 1,
  naming them), --series N and --series UID pick one;
- --iso bone/skin/otsu; --series on a non-DICOM source is a usage error.
"""
import json
import os
import sys
import tempfile

import numpy as np

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from clitest import check, failures, read_ply_arrays, run as run_cli  # noqa: E402

CLI, DIR = sys.argv[1], os.path.abspath(sys.argv[2])
CASES = json.load(open(os.path.join(DIR, "cases.json")))
TYPES = {"u8": "u1", "i8": "i1", "u16": "<u2", "i16": "<i2", "i32": "<i4", "f32": "<f4", "f64": "<f8"}


def run(args):
    return run_cli(CLI, args)


def series_args(case):
    return ["--series", case["series"]] if case.get("series") else []


def signed_volume(p, t):
    a, b, c = p[t[:, 0]].astype(float), p[t[:, 1]].astype(float), p[t[:, 2]].astype(float)
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


with tempfile.TemporaryDirectory() as tmp:
    # ---- defects: exit 1, the file and the reason, nothing written ----
    for name, c in CASES.items():
        if c["ok"]:
            continue
        out = os.path.join(tmp, "bad_" + name + ".ply")
        r = run(["extract", "--quiet", "-o", out, "--iso", "100"] + series_args(c) + c["sources"])
        lines = [l for l in r.stderr.splitlines() if l.strip()]
        check(r.returncode == 1, "%s: exit %d (%s)" % (name, r.returncode, r.stderr.strip()))
        check(lines and lines[0].startswith("isomend: ") and c["substring"] in r.stderr and DIR in lines[0],
              "%s: message %r lacks %r or a file of the series" % (name, r.stderr, c["substring"]))
        check(not os.path.exists(out), "%s: an output file was left" % name)
    check(os.listdir(tmp) == [], "temporary files left: %s" % os.listdir(tmp))

    # ---- good series: info, and the mesh equals the raw volume's ----
    for name, c in CASES.items():
        if not c["ok"]:
            continue
        axes = ["--grid-axes"] if c["axes"] == 1 else []
        r = run(["info", "--json", "-", "--quiet"] + series_args(c) + axes + c["sources"])
        check(r.returncode == 0, "%s: info exit %d: %s" % (name, r.returncode, r.stderr))
        if r.returncode:
            continue
        j = json.loads(r.stdout)
        check(j["kind"] == "dicom" and j["dims"] == c["dims"] and j["type"] == c["type"],
              "%s: info %s %s %s" % (name, j["kind"], j["dims"], j["type"]))
        check(np.allclose(j["spacing"], c["spacing"], rtol=1e-6) and np.allclose(j["origin"], c["origin"], atol=1e-4),
              "%s: spacing %s origin %s, expected %s %s" % (name, j["spacing"], j["origin"], c["spacing"], c["origin"]))
        A = np.array(c["affine"])
        identity = np.array_equal(A, np.hstack([np.eye(3), np.zeros((3, 1))]))
        check((j["world_transform"] is None) == identity and
              (identity or np.allclose(np.reshape(j["world_transform"], (3, 4)), A, atol=1e-6)),
              "%s: world transform %s, expected %s" % (name, j["world_transform"], A.tolist()))
        check(j["dicom"]["axes"] == ("grid" if c["axes"] == 1 else "patient"), "%s: axes" % name)
        if j["dicom"]["hounsfield"]:
            check(j["suggested_level"] == "bone" and j["suggested_iso"] == 300 and
                  j["dicom"]["levels"]["bone"] == 300 and j["dicom"]["levels"]["skin"] == -500,
                  "%s: CT levels %s" % (name, j["dicom"]["levels"]))
        # the raw twin: the expected volume with the series' spacing and own origin
        iso = "300" if j["dicom"]["hounsfield"] else "%g" % (0.5 + np.floor(np.median(
            np.fromfile(c["expected"], TYPES[c["type"]]))))
        dmesh, rmesh = os.path.join(tmp, name + ".ply"), os.path.join(tmp, name + ".raw.ply")
        r1 = run(["extract", "--quiet", "--pad", "--in-memory", "--iso", iso, "-o", dmesh] +
                 series_args(c) + axes + c["sources"])
        nx, ny, nz = c["dims"]
        r2 = run(["extract", "--quiet", "--pad", "--iso", iso, "-o", rmesh, c["expected"],
                  "--raw", "%d,%d,%d:%s" % (nx, ny, nz, c["type"]),
                  "--spacing", ",".join("%.17g" % v for v in j["spacing"]),
                  "--origin", ",".join("%.17g" % v for v in j["origin"])])
        check(r1.returncode == 0 and r2.returncode == 0, "%s: extract %s / raw %s" % (name, r1.stderr, r2.stderr))
        if r1.returncode or r2.returncode:
            continue
        # streamed (--max-memory between the two estimates): slices through the importer,
        # the mesh mapped to patient space batch by batch: the same bytes
        base = ["extract", "--quiet", "--pad", "--iso", iso] + series_args(c) + axes + c["sources"]
        p = run(base + ["-o", os.path.join(tmp, name + ".probe.ply"), "--json", "-"])
        if p.returncode == 0:
            e = json.loads(p.stdout)
            smesh = os.path.join(tmp, name + ".streamed.ply")
            r3 = run(base + ["-o", smesh, "--json", "-", "--max-memory",
                             str((e["memory_estimate"] + e["memory_streaming"]) // 2)])
            check(r3.returncode == 0 and json.loads(r3.stdout)["streamed"] and
                  open(smesh, "rb").read() == open(dmesh, "rb").read(),
                  "%s: the streamed DICOM mesh differs from the in-memory one: %s" % (name, r3.stderr))
        if c.get("slice_origins") is not None:
            # slices where they are (isomend_io.h): the raw twin is the evenly
            # spaced grid, so only its triangles are the same
            dv, dt = read_ply_arrays(dmesh)
            rv, rt = read_ply_arrays(rmesh)
            check(dv.shape == rv.shape and np.array_equal(dt, rt), "%s: not the raw mesh's triangles" % name)
        elif identity:
            check(open(dmesh, "rb").read() == open(rmesh, "rb").read(),
                  "%s: the DICOM mesh differs from the raw volume's mesh" % name)
        else:
            dv, dt = read_ply_arrays(dmesh)
            rv, rt = read_ply_arrays(rmesh)
            mapped = rv[:, :3].astype(float) @ A[:, :3].T + A[:, 3]
            normals = rv[:, 3:6].astype(float) @ A[:, :3].T
            check(dv.shape == rv.shape and np.array_equal(dt, rt), "%s: not the raw mesh's triangles" % name)
            if dv.shape == rv.shape:
                check(np.abs(dv[:, :3] - mapped).max() < 1e-4, "%s: positions are not A * raw" % name)
                check(np.abs(dv[:, 3:6] - normals).max() < 1e-5, "%s: normals are not R * raw" % name)
        # closed, oriented, outward
        rc = run(["check", "--json", "-", "--quiet", dmesh])
        rep = json.loads(rc.stdout)["check"] if rc.returncode == 0 else {}
        check(rc.returncode == 0 and rep.get("holes") == 0 and rep.get("border_edges") == 0 and rep.get("continuous"),
              "%s: the padded mesh is not closed: %s %s" % (name, rc.stdout, rc.stderr))
        v, t = read_ply_arrays(dmesh)
        check(signed_volume(v[:, :3], t) > 0, "%s: the surface faces inwards" % name)

    # ---- one command: a CT folder to a closed bone mesh in mm (default level) ----
    out = os.path.join(tmp, "bone.stl")
    r = run(["extract", os.path.join(DIR, "ct"), "--pad", "-o", out])
    check(r.returncode == 0 and "300 HU, the bone level" in r.stderr, "bone: %s" % r.stderr)
    rc = run(["check", "--json", "-", "--quiet", out])
    check(rc.returncode == 0 and json.loads(rc.stdout)["check"]["holes"] == 0, "bone.stl not closed")
    # the skull lies where the phantom has it, in mm: x within the position +- 40 * 0.7 mm
    ply = os.path.join(tmp, "bone.ply")
    run(["extract", os.path.join(DIR, "ct"), "--pad", "--quiet", "-o", ply])
    v, _ = read_ply_arrays(ply)
    p0 = np.array(CASES["ct_folder"]["p0"])
    lo, hi = v[:, :3].min(0), v[:, :3].max(0)
    size = np.array([40 * 0.7, 36 * 0.8, 30 * 1.25])
    check(np.all(lo >= p0 - 1e-3) and np.all(hi <= p0 + size) and np.all(hi - lo > 0.6 * size),
          "bone mesh box %s..%s not inside the series %s + %s" % (lo, hi, p0, size))
    # levels by name
    for level, want in (("bone", "300"), ("skin", "-500")):
        r = run(["extract", os.path.join(DIR, "ct"), "--iso", level, "--json", "-", "--quiet",
                 "-o", os.path.join(tmp, level + ".ply")])
        check(r.returncode == 0 and json.loads(r.stdout)["iso"] == float(want) and
              json.loads(r.stdout)["iso_level"] == level, "--iso %s: %s" % (level, r.stderr))
    r = run(["extract", os.path.join(DIR, "mr"), "--iso", "bone", "-o", os.path.join(tmp, "no.ply")])
    check(r.returncode == 2 and "Hounsfield" in r.stderr and not os.path.exists(os.path.join(tmp, "no.ply")),
          "--iso bone on MR: %d %s" % (r.returncode, r.stderr))
    r = run(["extract", os.path.join(DIR, "mr"), "--iso", "otsu", "--json", "-", "--quiet",
             "-o", os.path.join(tmp, "otsu.ply")])
    check(r.returncode == 0 and json.loads(r.stdout)["iso_level"] == "otsu", "--iso otsu: %s" % r.stderr)

    # ---- several series ----
    two = os.path.join(DIR, "two_series")
    r = run(["info", two])
    check(r.returncode == 0 and "choose one with --series" in r.stdout and r.stdout.count("UID ") == 2 and
          '"T1"' in r.stdout and '"CT head phantom"' in r.stdout, "info two series: %s %s" % (r.stdout, r.stderr))
    r = run(["info", two, "--json", "-", "--quiet"])
    j = json.loads(r.stdout) if r.returncode == 0 else {}
    check(len(j.get("series", [])) == 2 and j["series"][0]["modality"] == "CT" and j["series"][1]["images"] == 25,
          "info --json two series: %s" % r.stdout)
    r = run(["extract", two, "-o", os.path.join(tmp, "two.ply")])
    check(r.returncode == 1 and "2 DICOM series" in r.stderr and "T1" in r.stderr and
          not os.path.exists(os.path.join(tmp, "two.ply")), "extract two series: %s" % r.stderr)
    r = run(["info", two, "--series", "1"])
    check(r.returncode == 0 and "* " in r.stdout and "CT \"CT head phantom\"" in r.stdout,
          "info --series 1: %s" % r.stdout)
    # info text: what was ignored, the levels and which one extract uses
    r = run(["info", os.path.join(DIR, "ct")])
    check("1 DICOM object without pixel data, 1 file not DICOM" in r.stdout and
          "extract uses bone" in r.stdout and "(from: dicom, dicom, positions)" in r.stdout,
          "info ct: %s" % r.stdout)
    # --series / --grid-axes only for DICOM
    raw = CASES["ct_folder"]["expected"]
    r = run(["info", raw, "--raw", "40,36,30:i16", "--series", "1"])
    check(r.returncode == 2, "--series on raw: %d %s" % (r.returncode, r.stderr))

print("%d failures" % len(failures))
sys.exit(1 if failures else 0)
