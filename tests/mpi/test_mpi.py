#!/usr/bin/env python3
"""`mpirun -n N isomend-mpi extract` writes the file `isomend extract` writes.

For N = 1, 2, 3 and 5 ranks (mpirun --oversubscribe on this 2-core machine)
and sources of every kind (raw, NRRD raw and gzip, reversed axes, NaN
samples, a TIFF folder through the importer, the bundled MRI, a volume with
fewer slices than ranks, slices not evenly spaced: --slice-positions on a raw
volume and the TIFF folder, every rank reading the same positions file),
formats PLY, OBJ and STL and options (--pad,
--flip, --no-normals, methods mc, durst, dmc, tetra; the suggested iso when
--iso is not given), the mesh file is identical byte for byte to the one
`isomend extract` writes, and the JSON statistics (vertices, triangles and
their origins, cubes, case histogram, ambiguous faces, inverted combinations,
NaN samples) and the slices' geometry and warnings are the same.

Failures end every rank with one message naming the file and no output or
temporary file: a corrupt slice that only one rank reads, a write that fails
(the file size limit), a folder that does not exist, bad options, slice
positions that do not match the slices or a positions file that is missing.  The
methods with cube-private vertices (facial, gradient, asymptotic, mc33) on
N = 1, 2, 3 write `isomend extract`'s bytes too.

usage: test_mpi.py --isomend PATH --isomend-mpi PATH --mpirun PATH --samples DIR --work DIR
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import tifffile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import clitest  # noqa: E402
from clitest import fail  # noqa: E402

ENV = clitest.mpi_env()
STATS = ("vertices", "triangles", "triangles_by_origin", "cubes", "case_histogram",
         "ambiguous_faces", "inverted_combinations", "nan_samples", "iso", "iso_suggested",
         "geometry", "warnings")


class Tools:
    def __init__(self, a):
        self.exe = os.path.abspath(a.isomend)
        self.mpi = os.path.abspath(a.isomend_mpi)
        self.mpirun = a.mpirun
        self.work = a.work

    def single(self, args, out):
        return subprocess.run([self.exe, "extract", *args, "-o", out, "-q", "--json", "-"],
                              cwd=self.work, capture_output=True, text=True, timeout=600)

    def ranks(self, n, args, out, json_out=True, limit=None):
        extra = ["--json", "-"] if json_out else []
        prog = [self.mpi]
        mca = []
        if limit:  # the ranks only, not mpirun; no shared-memory transport (files too)
            prog = ["prlimit", "--fsize=%d" % limit, self.mpi]
            mca = ["--mca", "btl", "self,tcp"]
        return subprocess.run([self.mpirun, "--oversubscribe", *mca, "-n", str(n), *prog, "extract",
                               *args, "-o", out, "-q", *extra], cwd=self.work, capture_output=True,
                              text=True, timeout=900, env=ENV)


def nrrd(path, arr, encoding="raw", extra=""):
    import gzip
    t = {"uint8": "uint8", "uint16": "uint16", "int16": "int16", "float32": "float",
         "float64": "double"}[arr.dtype.name]
    nz, ny, nx = arr.shape
    data = arr.astype(arr.dtype.newbyteorder("<")).tobytes()
    with open(path, "wb") as f:
        f.write((f"NRRD0004\ntype: {t}\ndimension: 3\nsizes: {nx} {ny} {nz}\nendian: little\n"
                 f"encoding: {encoding}\n{extra}\n").encode())
        f.write(data if encoding == "raw" else gzip.compress(data, 6))


def volumes(work, samples):
    """[(name, args, format, option sets)]"""
    z, y, x = np.mgrid[0:37, 0:29, 0:31].astype(np.float64)
    gy = (np.sin(x / 2.3) * np.cos(y / 2.9) + np.sin(y / 2.9) * np.cos(z / 3.1) +
          np.sin(z / 3.1) * np.cos(x / 2.3)).astype(np.float32)
    gy.tofile(os.path.join(work, "gyroid.raw"))
    rng = np.random.default_rng(11)
    no = rng.integers(0, 4000, size=(41, 23, 27)).astype(np.float64)
    for ax in range(3):
        no = (no + np.roll(no, 1, ax) + np.roll(no, -1, ax)) / 3
    no = no.astype(np.uint16)
    nrrd(os.path.join(work, "noise_gz.nrrd"), no, "gzip")
    sp = (18.0 - np.sqrt((x - 14) ** 2 + (y - 13) ** 2 + (z - 19) ** 2)).astype(np.float32)
    sp[5:9, 10:14, 3:30] = np.nan  # NaN samples cut through the surface
    nrrd(os.path.join(work, "nan_sphere.nrrd"), sp, "raw",
         "space directions: (-0.5,0,0) (0,-0.75,0) (0,0,-1.5)\nspace origin: (3,4,5)\n")
    thin = gy[:3].copy()
    thin.tofile(os.path.join(work, "thin.raw"))
    os.makedirs(os.path.join(work, "tiffs"), exist_ok=True)
    for k in range(no.shape[0]):
        tifffile.imwrite(os.path.join(work, "tiffs", "s_%03d.tif" % k), no[k], compression="zlib")
    # slices not evenly spaced (issue 34): a spacing change, a missing slice, jitter
    gaps = 0.9 + 0.6 * (np.arange(36) >= 17) + 0.05 * np.sin(np.arange(36))
    gaps[25] *= 2
    with open(os.path.join(work, "gyroid_z.txt"), "w") as f:
        f.write("# z of each slice\n" + "\n".join(repr(v) for v in np.concatenate([[2.0], 2.0 + np.cumsum(gaps)])))
    tiff_z = ",".join(repr(v) for v in np.round(1.15 * np.arange(no.shape[0]) + 0.3, 1))
    mri = os.path.join(samples, "anatomical.nrrd")
    both = [["--iso", "0.2"], ["--iso", "0.2", "--pad", "--method", "mc"],
            ["--iso", "0.2", "--pad", "--method", "durst"], ["--iso", "0.2", "--pad", "--method", "tetra"],
            ["--iso", "0.2", "--flip", "--no-normals"]]
    return [
        ("gyroid raw", ["gyroid.raw", "--raw", "31,29,37:f32"], "ply", both),
        ("gyroid raw obj", ["gyroid.raw", "--raw", "31,29,37:f32"], "obj", both[:1] + both[3:]),
        ("noise gzip stl", ["noise_gz.nrrd"], "stl", [["--iso", "2000.5", "--pad"], []]),
        ("nan sphere reversed", ["nan_sphere.nrrd"], "ply", [["--iso", "1.5"], ["--pad"]]),
        ("tiff folder", ["tiffs"], "ply", [["--pad"], ["--iso", "1990.5", "--method", "tetra"]]),
        ("mri", [mri], "ply", [["--pad"]]),
        ("gyroid raw uneven slices", ["gyroid.raw", "--raw", "31,29,37:f32", "--slice-positions",
                                      "@gyroid_z.txt"], "ply", both[:2] + both[3:4]),
        ("gyroid raw uneven slices stl", ["gyroid.raw", "--raw", "31,29,37:f32", "--slice-positions",
                                          "@gyroid_z.txt"], "stl", both[:1]),
        ("tiff folder uneven slices", ["tiffs", "--slice-positions", tiff_z], "ply",
         [["--pad"], ["--iso", "1990.5", "--method", "tetra"]]),
        ("thin (3 slices)", ["thin.raw", "--raw", "31,29,3:f32"], "ply", [["--iso", "0.1"],
                                                                           ["--iso", "0.1", "--pad"]]),
    ]


def test_same_files(t, samples, dicom):
    n_ok = 0
    vols = volumes(t.work, samples)
    if dicom:  # gen_dicom.py's series: through the importer, mapped to patient space
        cases = json.load(open(os.path.join(dicom, "cases.json")))
        for case in ("ct_folder", "ct_oblique", "ct_feet_first", "mr_coronal",
                     # slices where they are (uneven gaps, rounded positions, tilt)
                     "rounded", "two_spacings", "tilt15", "missing_slice"):
            if case in cases:
                # CT series: also without --iso (the bone level, as isomend extract's)
                vols.append((f"dicom {case}", cases[case]["sources"], "ply", [["--pad", "--iso", "300"], ["--pad"]]
                             if case.startswith("ct") else [["--pad"]]))
    for name, src, fmt, sets in vols:
        for opts in sets:
            label = f"{name} {' '.join(opts) or '(suggested iso)'}"
            ref = os.path.join(t.work, "ref." + fmt)
            r = t.single(src + opts, ref)
            if r.returncode:
                fail(label, f"isomend extract: {r.stderr.strip()}")
                continue
            want = json.loads(r.stdout)
            data = open(ref, "rb").read()
            if want["triangles"] == 0:
                fail(label, "empty mesh: the comparison would prove little")
            if "--slice-positions" in src and want["geometry"]["uniform"]:
                fail(label, "the slice positions are evenly spaced: the comparison proves little")
            for n in (1, 2, 3, 5):
                out = os.path.join(t.work, f"mpi{n}.{fmt}")
                m = t.ranks(n, src + opts, out)
                if m.returncode:
                    fail(f"{label} -n {n}", f"exit {m.returncode}: {m.stderr.strip()[:600]}")
                    continue
                got = json.loads(m.stdout)
                warned = [l for l in m.stderr.splitlines() if l.startswith("isomend-mpi: warning: ")]
                if len(warned) != len(want["warnings"]):  # said once, by rank 0
                    fail(f"{label} -n {n}", f"warning lines {warned}, expected {want['warnings']}")
                if got["ranks"] != n:
                    fail(f"{label} -n {n}", f"ranks {got['ranks']}")
                for k in STATS:
                    if got[k] != want[k]:
                        fail(f"{label} -n {n}", f"{k}: {got[k]} vs {want[k]}")
                if open(out, "rb").read() != data:
                    fail(f"{label} -n {n}", f"the file differs from isomend extract's "
                                            f"({os.path.getsize(out)} vs {len(data)} bytes)")
                else:
                    n_ok += 1
                os.unlink(out)
            os.unlink(ref)
    left = [f for f in os.listdir(t.work) if ".tmp" in f or ".spool" in f]
    if left:
        fail("same files", f"left behind: {left}")
    print(f"ok   {n_ok} isomend-mpi files (N = 1, 2, 3, 5) equal isomend extract's byte for byte")


def expect_failure(t, name, n, args, out_dir, subs, code=None, limit=None, create=True):
    if create:
        os.makedirs(out_dir, exist_ok=True)
    m = t.ranks(n, args, os.path.join(out_dir, "m.ply"), json_out=False, limit=limit)
    ours = [l for l in m.stderr.splitlines() if l.startswith("isomend-mpi:")]
    if m.returncode == 0 or (code is not None and m.returncode != code):
        fail(name, f"exit {m.returncode}, expected {code or 'non-zero'}: {m.stderr.strip()[:400]}")
    if len(ours) != 1:
        fail(name, f"expected one isomend-mpi message, got {ours}")
    for s in subs:
        if not any(s in l for l in ours):
            fail(name, f"message {ours} lacks {s!r}")
    if os.path.isdir(out_dir) and os.listdir(out_dir):
        fail(name, f"left behind: {os.listdir(out_dir)}")
    shutil.rmtree(out_dir, ignore_errors=True)
    return ours


def test_failures(t):
    w = t.work
    # a corrupt slice in the middle of rank 1's slab (of 3): only that rank reads it
    bad = os.path.join(w, "tiffs_bad")
    shutil.copytree(os.path.join(w, "tiffs"), bad)
    victim = os.path.join(bad, "s_020.tif")
    with tifffile.TiffFile(victim) as tf:
        off, size = tf.pages[0].dataoffsets[0], tf.pages[0].databytecounts[0]
    with open(victim, "r+b") as f:
        f.seek(off + size // 2)
        chunk = bytearray(f.read(16))
        f.seek(off + size // 2)
        f.write(bytes(b ^ 0x5A for b in chunk))
    r = t.single(["tiffs_bad", "--iso", "1990.5"], os.path.join(w, "single.ply"))
    if r.returncode == 0 or "s_020.tif" not in r.stderr:
        fail("corrupt slice (isomend extract)", f"exit {r.returncode}: {r.stderr.strip()}")
    msg = expect_failure(t, "corrupt slice on rank 1", 3, ["tiffs_bad", "--iso", "1990.5"],
                         os.path.join(w, "out_corrupt"), ["s_020.tif", "rank 1 of 3"], 1)
    print(f"ok   a corrupt slice read by one rank of 3 ends every rank: {msg[0] if msg else ''}")

    # the file size limit (prlimit) on the ranks: the scratch files (1 rank) or the
    # shared file (3 ranks, each part below the limit, the file above it) fail
    for n in (1, 3):
        expect_failure(t, f"write failure -n {n}", n, ["gyroid.raw", "--raw", "31,29,37:f32", "--iso", "0.2"],
                       os.path.join(w, f"out_fsize{n}"), ["m.ply", "write"], 1, limit=96 * 1024)
    print("ok   a write failure (file size limit) ends every rank, no file left")

    expect_failure(t, "missing folder", 2, ["gyroid.raw", "--raw", "31,29,37:f32", "--iso", "0.2"],
                   os.path.join(w, "out_missing", "no", "such"), ["no/such", "cannot create"], 1,
                   create=False)
    shutil.rmtree(os.path.join(w, "out_missing"), ignore_errors=True)
    expect_failure(t, "bad option", 3, ["gyroid.raw", "--raw", "31,29,37:f32", "--iso", "x"],
                   os.path.join(w, "out_bad"), ["--iso"], 2)
    expect_failure(t, "bad slice file", 2, ["gyroid.raw", "--raw", "31,29,38:f32", "--iso", "0.2"],
                   os.path.join(w, "out_size"), ["gyroid.raw"], 1)
    expect_failure(t, "bad slice positions", 3, ["gyroid.raw", "--raw", "31,29,37:f32", "--iso", "0.2",
                                                 "--slice-positions", "0,1,2"],
                   os.path.join(w, "out_positions"), ["--slice-positions", "3 positions", "37 slices"], 2)
    expect_failure(t, "missing positions file", 2, ["gyroid.raw", "--raw", "31,29,37:f32", "--iso", "0.2",
                                                    "--slice-positions", "@no_such_z.txt"],
                   os.path.join(w, "out_positions_file"), ["--slice-positions", "no_such_z.txt"], 1)
    print("ok   missing folder, bad option, bad size, bad slice positions: one message, nothing left")
    # the methods with cube-private vertices split too (the core's pieces own
    # layer k's private vertices with slice k)
    for method in ("facial", "gradient", "asymptotic", "mc33"):
        args = ["gyroid.raw", "--raw", "31,29,37:f32", "--iso", "0.2", "--method", method, "--pad"]
        ref = os.path.join(w, f"{method}.ply")
        r = t.single(args, ref)
        for n in (1, 2, 3):
            out = os.path.join(w, f"{method}_{n}.ply")
            m = t.ranks(n, args, out)
            if r.returncode or m.returncode or open(ref, "rb").read() != open(out, "rb").read():
                fail(f"{method} -n {n}", f"{r.stderr.strip()} {m.stderr.strip()[:300]}")
    print("ok   facial, gradient, asymptotic, mc33 on N = 1, 2, 3 ranks: isomend extract's bytes")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--isomend-mpi", required=True)
    ap.add_argument("--mpirun", required=True)
    ap.add_argument("--samples", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--dicom", help="gen_dicom.py's folder (optional)")
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    t = Tools(a)
    test_same_files(t, os.path.abspath(a.samples), a.dicom)
    test_failures(t)
    return clitest.summary()


if __name__ == "__main__":
    sys.exit(main())
