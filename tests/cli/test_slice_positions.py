#!/usr/bin/env python3
"""`--slice-positions`: slices meshed where they are (issue 34), on the command line.

A raw volume, a reversed NRRD, a built-in volume and (with the importer) a
TIFF stack of the same samples are meshed with slice positions that are not
evenly spaced: a jittered set (positions rounded to 0.1, as scanners write
them), a set with a spacing change part-way and a missing slice, and a set
whose gaps differ by less than 1 %.  For each:

  * the mesh has the evenly spaced mesh's triangles (the same index array)
    and vertex count, x and y unchanged, and every vertex's z lies where its
    slice interval puts it: a vertex at index height k + f in the uniform
    mesh lies at z_k + f (z_k+1 - z_k), so within [z_k, z_k+1];
  * `--slice-positions @FILE` (comments, blank lines) gives the inline list's
    bytes, and evenly spaced positions give the bytes of --spacing/--origin;
  * the TIFF stack's mesh is the raw volume's byte for byte, and both report
    the same geometry;
  * `info --json` and `extract --json` report the geometry (uniform, gaps
    median/min/max, tilt, long and uneven gaps, the warning) as computed here
    by the rule of isomend_io.h; a warning is one line on stderr
    "isomend: warning: SOURCE: ..." (with --quiet too), the mesh is written
    and the exit status is 0; gaps within 1 % give no warning;
  * the streamed path (--max-memory between the two paths' needs, as
    test_stream.py forces it) writes the in-memory bytes for PLY, OBJ, STL
    and option sets (--pad, --no-normals --flip, methods mc and tetra).

Errors: a count that is not the number of slices, positions that do not
increase, a value that is not a number, NaN, inf, an empty value, a missing
file, a bad line in a file (named FILE:LINE), a file without positions, and
--slice-positions on a DICOM series: exit 2 (1 for a file that cannot be
read), one line naming --slice-positions (and the file), no output or
temporary file.  With the importer, a DICOM series with a missing slice
reports its own geometry and warning (from isomend_io_geometry_info()).

usage: test_slice_positions.py --isomend PATH --work DIR
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import clitest  # noqa: E402
from clitest import fail  # noqa: E402

NX, NY, NZ = 27, 23, 19


def run(exe, args, cwd):
    p = subprocess.run([exe, *args], cwd=cwd, capture_output=True, text=True, timeout=300,
                       stdin=subprocess.DEVNULL)
    return p.returncode, p.stdout, p.stderr


def leftovers(folder):
    return [f for f in os.listdir(folder) if ".tmp" in f or ".spool" in f]


# ------------------------------------------------------------------ volumes and positions

def blobs():
    """Two blobs and a tilted slab: surfaces crossing every slice interval."""
    z, y, x = np.mgrid[0:NZ, 0:NY, 0:NX].astype(np.float64)
    a = 9.0 - np.sqrt((x - 10) ** 2 + (y - 11) ** 2 + ((z - 8) * 1.3) ** 2)
    b = 6.0 - np.sqrt((x - 19) ** 2 + (y - 8) ** 2 + (z - 12) ** 2)
    slab = 2.5 - np.abs(0.3 * x + 0.2 * y - 0.8 * z + 4)
    return np.maximum(np.maximum(a, b), slab).astype(np.float32)


def position_sets():
    """{name: (z positions, warning expected)}"""
    rng = np.random.default_rng(34)
    # a scanner's positions: 1.15 mm steps from 12.3, written rounded to 0.1
    jitter = np.round(12.3 + 1.15 * np.arange(NZ), 1)
    # 0.8 steps, then 1.4 from slice 9, and slice 14 missing (a 2.8 gap)
    gaps = [0.8] * 8 + [1.4] * (NZ - 9)
    gaps[13] = 2.8
    change = np.concatenate([[-3.0], -3.0 + np.cumsum(gaps)])
    # gaps within 0.5 % of 2: not uniform (slice origins), but no warning
    small = np.concatenate([[5.0], 5.0 + np.cumsum(2.0 * (1 + 0.005 * rng.uniform(-1, 1, NZ - 1)))])
    return {"jitter": (jitter, True), "change": (change, True), "small": (small, False)}


def expected_geometry(z):
    """isomend_io.h's rule: the median is the upper middle gap; uneven gaps
    differ from it by more than 1 %, long ones exceed 1.5x it; uniform when
    every slice lies within 1e-6 of the mean gap of the evenly spaced grid."""
    g = np.diff(z)
    med = float(np.sort(g)[len(g) // 2])
    mean = (z[-1] - z[0]) / (len(z) - 1)
    off = float(np.max(np.abs(z - (z[0] + np.arange(len(z)) * mean))))
    return {"uniform": off <= 1e-6 * mean, "gap_median": med, "gap_min": float(g.min()),
            "gap_max": float(g.max()), "tilt_degrees": 0.0,
            "long_gaps": int(np.sum(g > 1.5 * med)),
            "uneven_gaps": int(np.sum(np.abs(g - med) > 0.01 * med)), "max_offset": off}


def check_geometry(name, got, z, warn, source_from="--slice-positions"):
    want = expected_geometry(z)
    geo = got.get("geometry")
    if not isinstance(geo, dict):
        fail(name, f"no geometry in the JSON: {sorted(got)}")
        return
    for k in ("uniform", "long_gaps", "uneven_gaps"):
        if geo.get(k) != want[k]:
            fail(name, f"geometry {k}: {geo.get(k)}, expected {want[k]}")
    for k in ("gap_median", "gap_min", "gap_max", "tilt_degrees", "max_offset"):
        if not abs(geo.get(k, 1e300) - want[k]) <= 1e-9 * max(1.0, abs(want[k])):
            fail(name, f"geometry {k}: {geo.get(k)}, expected {want[k]}")
    if geo.get("from") != source_from:
        fail(name, f"geometry from {geo.get('from')!r}, expected {source_from!r}")
    if bool(geo.get("warning")) != warn:
        fail(name, f"warning {geo.get('warning')!r}, expected {'one' if warn else 'none'}")
    if got.get("warnings") != ([geo["warning"]] if warn else []):
        fail(name, f"warnings {got.get('warnings')!r} vs the geometry's {geo.get('warning')!r}")


def warning_lines(err):
    return [l for l in err.splitlines() if l.startswith("isomend: warning: ")]


def check_warning(name, err, source, warn, geo=None):
    lines = warning_lines(err)
    if len(lines) != (1 if warn else 0):
        fail(name, f"{len(lines)} warning lines, expected {1 if warn else 0}: {err.strip()!r}")
    elif warn:
        if not lines[0].startswith(f"isomend: warning: {source}: "):
            fail(name, f"the warning does not name {source}: {lines[0]!r}")
        if geo and geo.get("warning") and not lines[0].endswith(geo["warning"]):
            fail(name, f"the warning line {lines[0]!r} is not the JSON's {geo['warning']!r}")
        if "median" not in lines[0]:
            fail(name, f"the warning does not say what is uneven: {lines[0]!r}")


# ------------------------------------------------------------------ the mesh where the slices are

def index_heights(verts, origin_z, spacing_z):
    return (verts[:, 2].astype(np.float64) - origin_z) / spacing_z


def check_placed(name, uni_path, uni_json, pos_path, z, nz, pad=False):
    """The mesh at positions z against the evenly spaced mesh of the same samples."""
    u_v, u_t = clitest.read_ply_arrays(uni_path)
    p_v, p_t = clitest.read_ply_arrays(pos_path)
    if len(u_v) != len(p_v) or len(u_t) != len(p_t) or not np.array_equal(u_t, p_t):
        fail(name, f"not the evenly spaced mesh's triangles: {len(p_v)}/{len(p_t)} vs "
                   f"{len(u_v)}/{len(u_t)} vertices/triangles")
        return False
    if len(u_t) < 500:
        fail(name, f"only {len(u_t)} triangles: the comparison would prove little")
    if not np.allclose(p_v[:, :2], u_v[:, :2], rtol=0, atol=1e-4):
        fail(name, "x or y moved: the slices share their in-plane axes")
    # heights in the uniform grid's index units -> where the positions put them
    h = index_heights(u_v, uni_json["origin"][2], uni_json["spacing"][2])
    zz = np.asarray(z, dtype=np.float64)
    if pad:  # the padding slices lie one gap beyond the ends
        zz = np.concatenate([[zz[0] - (zz[1] - zz[0])], zz, [zz[-1] + (zz[-1] - zz[-2])]])
        h = h + 1
    k = np.clip(np.floor(h + 1e-6).astype(np.int64), 0, len(zz) - 2)
    f = h - k
    want = zz[k] + f * (zz[k + 1] - zz[k])
    got = p_v[:, 2].astype(np.float64)
    tol = 1e-4 * max(1.0, float(np.abs(zz).max()))
    bad = np.abs(got - want) > tol
    lo = np.minimum(zz[k], zz[k + 1]) - tol
    hi = np.maximum(zz[k], zz[k + 1]) + tol
    outside = (got < lo) | (got > hi)
    if bad.any() or outside.any():
        i = int(np.argmax(np.abs(got - want)))
        fail(name, f"{int(bad.sum())} vertices off their slice interval's place, {int(outside.sum())} "
                   f"outside [z_k, z_k+1] (worst: z {got[i]}, expected {want[i]}, slice {k[i]})")
        return False
    if not (f > 0.05).any() or len(np.unique(k)) < nz - 3:
        fail(name, "the vertices do not cover the slice intervals: the check proves little")
    return True


def write_positions_file(path, z):
    with open(path, "w") as fh:
        fh.write("# slice positions, one z a line\n\n")
        for i, v in enumerate(z):
            fh.write(f"  {float(v)!r}   # slice {i}\n" if i % 3 == 0 else f"{float(v)!r}\n")
            if i % 5 == 4:
                fh.write("\n# ---\n")


def inline(z):
    return ",".join(repr(float(v)) for v in z)


def extract(exe, work, args, out, extra=()):
    """(exit code, JSON, stderr) of an in-memory extraction to `out`."""
    rc, o, err = run(exe, ["extract", *args, "-o", out, "--json", "-", *extra], work)
    return rc, (json.loads(o) if rc == 0 else None), err


def test_placed(exe, work, sources):
    """The placement, the @FILE form, the uniform case and the geometry report."""
    n = 0
    sets = position_sets()
    for sname, args, iso, nz in sources:
        base = args + ["--iso", iso]
        rc, uj, err = extract(exe, work, base, "uni.ply", ["-q"])
        if rc:
            fail(f"{sname} uniform", err.strip())
            continue
        if uj["geometry"]["uniform"] is not True or uj["warnings"] != [] or warning_lines(err):
            fail(f"{sname} uniform", f"geometry {uj['geometry']} warnings {uj['warnings']}")
        for pname, (z, warn) in sets.items():
            label = f"{sname} {pname}"
            rc, pj, err = extract(exe, work, base + ["--slice-positions", inline(z)], "pos.ply")
            if rc:
                fail(label, f"exit {rc}: {err.strip()}")
                continue
            check_geometry(label, pj, z, warn)
            check_warning(label, err, args[0], warn, pj["geometry"])
            if pj["check"] is None or not pj["check"]["continuous"]:
                fail(label, f"the mesh at the positions is not continuous: {pj['check']}")
            if check_placed(label, os.path.join(work, "uni.ply"), uj, os.path.join(work, "pos.ply"),
                            z, nz):
                n += 1
            # @FILE: the same bytes; --quiet still warns
            write_positions_file(os.path.join(work, "z.txt"), z)
            rc, fj, err = extract(exe, work, base + ["--slice-positions", "@z.txt", "-q"], "file.ply")
            if rc:
                fail(f"{label} @FILE", err.strip())
            else:
                if not clitest.same_file(os.path.join(work, "pos.ply"), os.path.join(work, "file.ply")):
                    fail(f"{label} @FILE", "not the inline list's mesh")
                check_warning(f"{label} @FILE --quiet", err, args[0], warn)
                os.unlink(os.path.join(work, "file.ply"))
            # info reports the same geometry
            rc, o, err = run(exe, ["info", *args, "--slice-positions", "@z.txt", "--json", "-"], work)
            if rc:
                fail(f"{label} info", err.strip())
            else:
                ij = json.loads(o)
                check_geometry(f"{label} info", ij, z, warn)
                check_warning(f"{label} info", err, args[0], warn, ij["geometry"])
                if ij["geometry"] != pj["geometry"]:
                    fail(f"{label} info", f"info's geometry {ij['geometry']} is not extract's "
                                          f"{pj['geometry']}")
            rc, o, err = run(exe, ["info", *args, "--slice-positions", "@z.txt"], work)
            if rc or "not evenly spaced" not in o:
                fail(f"{label} info text", f"exit {rc}, no 'not evenly spaced' line: {o[-600:]!r}")
            os.unlink(os.path.join(work, "pos.ply"))
        # evenly spaced positions: the grid of --spacing/--origin, byte for byte
        zu = 4.0 + 0.75 * np.arange(nz)
        rc, a, err = extract(exe, work, base + ["--slice-positions", inline(zu), "-q"], "even.ply")
        rc2, b, err2 = extract(exe, work, base + ["--spacing", "1,1,0.75", "--origin", "0,0,4", "-q"],
                               "sp.ply")
        if sname == "nrrd reversed":  # its x and y are the header's
            rc2, b, err2 = extract(exe, work, base + ["--spacing", "0.5,1.25,0.75", "--origin",
                                                      f"{uj['origin'][0]},{uj['origin'][1]},4", "-q"],
                                   "sp.ply")
        if rc or rc2:
            fail(f"{sname} even positions", f"{err.strip()} {err2.strip()}")
        else:
            if not clitest.same_file(os.path.join(work, "even.ply"), os.path.join(work, "sp.ply")):
                fail(f"{sname} even positions", "not the --spacing/--origin mesh byte for byte")
            if a["geometry"]["uniform"] is not True or a["warnings"] or warning_lines(err):
                fail(f"{sname} even positions", f"geometry {a['geometry']}")
            if a["spacing"][2] != 0.75 or a["origin"][2] != 4.0:
                fail(f"{sname} even positions", f"spacing {a['spacing']} origin {a['origin']}")
            for f in ("even.ply", "sp.ply"):
                os.unlink(os.path.join(work, f))
        os.unlink(os.path.join(work, "uni.ply"))
    print(f"ok   {n} meshes at uneven slice positions: the uniform mesh's triangles, every vertex "
          f"in its slice interval; @FILE, info, the geometry and its warning")


def test_same_sources(exe, work, have_stack):
    """A TIFF stack of the same samples: the raw volume's mesh and geometry."""
    if not have_stack:
        print("skip the TIFF stack (no importer)")
        return
    z, warn = position_sets()["change"]
    pos = ["--slice-positions", inline(z)]
    for opts in ([], ["--pad"], ["--method", "tetra"]):
        rc, a, err = extract(exe, work, ["blobs.raw", "--raw", f"{NX},{NY},{NZ}:f32", "--iso", "0.5",
                                         *pos, *opts, "-q"], "raw.ply")
        rc2, b, err2 = extract(exe, work, ["tiffs", "--iso", "0.5", *pos, *opts, "-q"], "tif.ply")
        label = f"tiff stack {' '.join(opts) or 'default'}"
        if rc or rc2:
            fail(label, f"{err.strip()} {err2.strip()}")
            continue
        if not clitest.same_file(os.path.join(work, "raw.ply"), os.path.join(work, "tif.ply")):
            fail(label, "the stack's mesh is not the raw volume's")
        if a["geometry"] != b["geometry"] or a["warnings"] != b["warnings"]:
            fail(label, f"geometry {b['geometry']} vs the raw volume's {a['geometry']}")
        check_warning(label, err2, "tiffs", warn, b["geometry"])
        for f in ("raw.ply", "tif.ply"):
            os.unlink(os.path.join(work, f))
    print("ok   a TIFF stack with --slice-positions: the raw volume's bytes and geometry")


def test_streamed(exe, work, sources):
    """The streamed mesh (the default, slices read one by one): the in-memory bytes and check."""
    z, _ = position_sets()["change"]
    pairs = 0
    for sname, args, iso, nz in sources:
        for fmt in ("ply", "obj", "stl"):
            for opts in ([], ["--pad"], ["--no-normals", "--flip"], ["--method", "mc", "--pad"],
                         ["--method", "tetra"]):
                if fmt != "ply" and opts and opts[0] == "--method":
                    continue
                base = args + ["--iso", iso, "--slice-positions", inline(z), *opts, "-q"]
                label = f"streamed {sname} {fmt} {' '.join(opts) or 'default'}"
                rc, j, err = extract(exe, work, base + ["--in-memory"], f"mem.{fmt}")
                if rc:
                    fail(label, err.strip())
                    continue
                rc, s, err = extract(exe, work, base, f"str.{fmt}")
                if rc:
                    fail(label, err.strip())
                    continue
                if j["streamed"] or not s["streamed"] or s["volume_loaded"]:
                    fail(label, f"streamed {j['streamed']} / {s['streamed']}")
                if j["check"] is None or s["check"] != j["check"]:
                    fail(label, f"check {s['check']} streamed, {j['check']} in memory")
                if not clitest.same_file(os.path.join(work, f"mem.{fmt}"), os.path.join(work, f"str.{fmt}")):
                    fail(label, "the streamed mesh differs from the in-memory one")
                elif j["triangles"] < 500:
                    fail(label, f"{j['triangles']} triangles: the comparison proves little")
                else:
                    pairs += 1
                if s["geometry"] != j["geometry"]:
                    fail(label, f"geometry {s['geometry']} vs {j['geometry']}")
                for f in (f"mem.{fmt}", f"str.{fmt}"):
                    os.unlink(os.path.join(work, f))
    if leftovers(work):
        fail("streamed", f"left behind: {leftovers(work)}")
    print(f"ok   {pairs} streamed meshes at uneven slice positions equal the in-memory ones")


# ------------------------------------------------------------------ errors

def expect_error(exe, work, name, args, code, subs):
    out_dir = os.path.join(work, "err")
    os.makedirs(out_dir, exist_ok=True)
    rc, out, err = run(exe, [a.replace("OUT/", "err/") for a in args], work)
    lines = [l for l in err.splitlines() if l.strip()]
    if rc != code:
        fail(name, f"exit {rc}, expected {code}: {err.strip()}")
    if len(lines) != 1 or not lines[0].startswith("isomend: "):
        fail(name, f"expected one 'isomend: ' line, got {lines}")
    for s in subs:
        if s not in err:
            fail(name, f"message {err.strip()!r} lacks {s!r}")
    if os.listdir(out_dir):
        fail(name, f"left behind: {os.listdir(out_dir)}")
    shutil.rmtree(out_dir)


def test_errors(exe, work, have_stack, dicom):
    raw = ["blobs.raw", "--raw", f"{NX},{NY},{NZ}:f32", "--iso", "0.5"]
    good = [float(v) for v in range(NZ)]
    with open(os.path.join(work, "bad_line.txt"), "w") as fh:
        fh.write("# z\n0\n1\n\n2.5 # fine\nslice 3\n")
    with open(os.path.join(work, "comments.txt"), "w") as fh:
        fh.write("# nothing but comments\n\n   \n# z\n")
    with open(os.path.join(work, "short.txt"), "w") as fh:
        fh.write("\n".join(str(v) for v in good[:-1]) + "\n")
    bad = [
        ("count short", inline(good[:-1]), 2, [f"{NZ - 1} positions", f"{NZ} slices", "blobs.raw"]),
        ("count long", inline(good + [99.0]), 2, [f"{NZ + 1} positions", f"{NZ} slices"]),
        ("count in a file", "@short.txt", 2, [f"{NZ - 1} positions", f"{NZ} slices"]),
        ("equal", inline(good[:5] + [4.0] + good[6:]), 2, ["increase", "slice 5"]),
        ("decreasing", inline(good[:7] + [2.0] + good[8:]), 2, ["increase", "slice 7"]),
        ("not a number", inline(good[:3]) + ",1O," + inline(good[5:]), 2, ["'1O'", "not a number"]),
        ("nan", inline(good[:-1]) + ",nan", 2, ["'nan'", "not a finite number"]),
        ("inf", "-inf," + inline(good[1:]), 2, ["'-inf'", "not a finite number"]),
        ("overflow", inline(good[:-1]) + ",1e999", 2, ["'1e999'", "not a finite number"]),
        ("empty value", inline(good[:4]) + ",," + inline(good[5:]), 2, ["not a number"]),
        ("trailing comma", inline(good) + ",", 2, ["not a number"]),
        ("empty", "", 2, ["empty"]),
        ("missing file", "@no_such_positions.txt", 1, ["no_such_positions.txt", "cannot read"]),
        ("bad line", "@bad_line.txt", 2, ["bad_line.txt:6", "'slice 3'", "not a number"]),
        ("no positions", "@comments.txt", 2, ["comments.txt", "no positions"]),
    ]
    for name, value, code, subs in bad:
        expect_error(exe, work, f"error {name}", ["extract", *raw, "-o", "OUT/m.ply",
                                                  "--slice-positions", value], code,
                     ["--slice-positions", *subs])
        expect_error(exe, work, f"error {name} (json)", ["extract", *raw, "-o", "OUT/m.ply",
                                                         "--json", "OUT/m.json",
                                                         "--slice-positions", value], code,
                     ["--slice-positions"])
    for name, value, code, subs in bad[:1] + bad[3:4] + bad[12:13]:
        expect_error(exe, work, f"info {name}", ["info", *raw[:3], "--json", "OUT/i.json",
                                                 "--slice-positions", value], code,
                     ["--slice-positions", *subs])
    expect_error(exe, work, "given twice", ["extract", *raw, "-o", "OUT/m.ply", "--slice-positions",
                                            inline(good), "--slice-positions", inline(good)], 2,
                 ["--slice-positions", "twice"])
    expect_error(exe, work, "missing value", ["extract", *raw, "-o", "OUT/m.ply", "--slice-positions"],
                 2, ["--slice-positions", "missing value"])
    expect_error(exe, work, "check refuses it", ["check", "x.ply", "--slice-positions", "0,1"], 2,
                 ["--slice-positions", "check"])
    if have_stack:
        expect_error(exe, work, "stack count", ["extract", "tiffs", "--iso", "0.5", "-o", "OUT/m.ply",
                                                "--slice-positions", inline(good[:-2])], 2,
                     ["--slice-positions", f"{NZ - 2} positions", f"{NZ} slices"])
        expect_error(exe, work, "stack not increasing", ["extract", "tiffs", "--iso", "0.5", "-o",
                                                         "OUT/m.ply", "--slice-positions",
                                                         inline(good[:9] + [1.0] + good[10:])], 2,
                     ["--slice-positions", "increase", "slice 9"])
    if dicom:
        expect_error(exe, work, "dicom", ["extract", dicom["even"], "--iso", "100", "-o", "OUT/m.ply",
                                          "--slice-positions", "0,1,2,3,4,5,6,7"], 2,
                     ["--slice-positions", "DICOM"])
    print(f"ok   {2 * len(bad) + 7 + 2 * have_stack + bool(dicom)} bad --slice-positions: one message "
          f"naming the option, exit 2 (1 for an unreadable file), nothing written")


# ------------------------------------------------------------------ DICOM: the series' own positions

def write_dicom(folder, vol, positions):
    """A CT series of vol [z, y, x] (u16) with slice k at positions[k] (mm)."""
    import pydicom
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid
    os.makedirs(folder, exist_ok=True)
    series, study, frame = generate_uid(), generate_uid(), generate_uid()
    for k in range(vol.shape[0]):
        ds = Dataset()
        ds.SOPClassUID = "1.2.840.10008.5.1.4.1.1.2"
        ds.SOPInstanceUID = generate_uid()
        ds.StudyInstanceUID, ds.SeriesInstanceUID, ds.FrameOfReferenceUID = study, series, frame
        ds.Modality = "CT"
        ds.PatientName, ds.PatientID = "Phantom^Isomend", "ISOMEND-TEST"
        ds.SeriesNumber, ds.InstanceNumber = 1, k + 1
        ds.ImagePositionPatient = ["0", "0", "%.10g" % positions[k]]
        ds.ImageOrientationPatient = ["1", "0", "0", "0", "1", "0"]
        ds.PixelSpacing = ["1", "1"]
        ds.SliceThickness = "1"
        ds.SamplesPerPixel = 1
        ds.PhotometricInterpretation = "MONOCHROME2"
        ds.Rows, ds.Columns = vol.shape[1], vol.shape[2]
        ds.BitsAllocated = ds.BitsStored = 16
        ds.HighBit = 15
        ds.PixelRepresentation = 0
        ds.PixelData = np.ascontiguousarray(vol[k]).astype("<u2").tobytes()
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = ds.SOPClassUID
        meta.MediaStorageSOPInstanceUID = ds.SOPInstanceUID
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        ds.file_meta = meta
        ds.is_little_endian, ds.is_implicit_VR = True, False
        ds.preamble = b"\0" * 128
        pydicom.dcmwrite(os.path.join(folder, "IMG%04d.dcm" % k), ds, write_like_original=False)


def make_dicom(work):
    try:
        import pydicom  # noqa: F401
    except ImportError:
        return None
    vol = (blobs()[:8] * 100 + 1000).clip(0, 4000).astype(np.uint16)
    write_dicom(os.path.join(work, "dcm_even"), vol, [10.0 + 2.0 * k for k in range(8)])
    # slice 5 of 9 missing: a 4 mm gap among 2 mm ones
    write_dicom(os.path.join(work, "dcm_gap"), vol, [10, 12, 14, 16, 18, 22, 24, 26])
    return {"even": "dcm_even", "gap": "dcm_gap", "gap_z": [10, 12, 14, 16, 18, 22, 24, 26]}


def test_dicom(exe, work, dicom):
    """The series' own geometry: reported, warned about, meshed (exit 0)."""
    for name, warn in (("even", False), ("gap", True)):
        rc, o, err = run(exe, ["info", dicom[name], "--json", "-"], work)
        if rc:
            fail(f"dicom {name} info", err.strip())
            continue
        j = json.loads(o)
        geo = j.get("geometry", {})
        if geo.get("from") != "dicom" or geo.get("uniform") is not (not warn):
            fail(f"dicom {name} info", f"geometry {geo}")
        check_warning(f"dicom {name} info", err, dicom[name], warn, geo)
        if warn:
            g = np.diff(dicom["gap_z"])
            if (geo.get("long_gaps") != 1 or geo.get("gap_median") != 2 or geo.get("gap_max") != 4
                    or geo.get("gap_min") != 2 or abs(geo.get("tilt_degrees", 1)) > 1e-9):
                fail(f"dicom {name} info", f"geometry {geo}, gaps {list(g)}")
            if j.get("warnings") != [geo.get("warning")]:
                fail(f"dicom {name} info", f"warnings {j.get('warnings')}")
        rc, j, err = extract(exe, work, [dicom[name], "--iso", "1500"], f"dcm_{name}.ply")
        if rc:
            fail(f"dicom {name} extract", err.strip())
            continue
        check_warning(f"dicom {name} extract", err, dicom[name], warn, j["geometry"])
        if j["geometry"] != geo or j["triangles"] == 0:
            fail(f"dicom {name} extract", f"geometry {j['geometry']} vs info's {geo}")
        if warn:  # the mesh spans the series' own 16 mm, not 7 evenly spaced gaps
            v, _ = clitest.read_ply_arrays(os.path.join(work, f"dcm_{name}.ply"))
            if not (v[:, 2].max() > 22.0):
                fail(f"dicom {name} extract", f"z up to {v[:, 2].max()}: not at the slices' positions")
        os.unlink(os.path.join(work, f"dcm_{name}.ply"))
    print("ok   DICOM series: their own geometry in info/extract --json, one warning for a gap")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    exe = os.path.abspath(a.isomend)
    work = a.work
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    rc, out, _ = run(exe, ["--version"], work)
    have_stack = "slice-stack importer: yes" in out
    vol = blobs()
    vol.tofile(os.path.join(work, "blobs.raw"))
    # NRRD whose axes all point backwards: the positions apply to the slices as presented
    with open(os.path.join(work, "rev.nrrd"), "wb") as fh:
        fh.write((f"NRRD0004\ntype: float\ndimension: 3\nsizes: {NX} {NY} {NZ}\nendian: little\n"
                  "encoding: raw\nspace directions: (-0.5,0,0) (0,-1.25,0) (0,0,-2)\n"
                  "space origin: (3,4,5)\n\n").encode())
        fh.write(vol.tobytes())
    sources = [("raw", ["blobs.raw", "--raw", f"{NX},{NY},{NZ}:f32"], "0.5", NZ),
               ("nrrd reversed", ["rev.nrrd"], "0.5", NZ)]
    if have_stack:
        import tifffile
        os.makedirs(os.path.join(work, "tiffs"))
        for k in range(NZ):
            tifffile.imwrite(os.path.join(work, "tiffs", "s_%03d.tif" % k), vol[k])
        sources.append(("tiff stack", ["tiffs"], "0.5", NZ))
    test_placed(exe, work, sources)
    # a built-in volume takes them too (4 slices)
    rc, j, err = extract(exe, work, ["builtin:f2", "--iso", "0", "--slice-positions", "0,0.5,2,2.25"],
                         "f2.ply")
    if rc or j["geometry"]["uniform"] or len(warning_lines(err)) != 1:
        fail("builtin", f"exit {rc}: {err.strip()}")
    else:
        os.unlink(os.path.join(work, "f2.ply"))
    test_same_sources(exe, work, have_stack)
    test_streamed(exe, work, sources[:1] + sources[2:])
    dicom = make_dicom(work) if have_stack else None
    test_errors(exe, work, have_stack, dicom)
    if dicom:
        test_dicom(exe, work, dicom)
    if leftovers(work):
        fail("leftovers", str(leftovers(work)))
    return clitest.summary()


if __name__ == "__main__":
    sys.exit(main())
