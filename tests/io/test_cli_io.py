#!/usr/bin/env python3
"""`isomend info` and `isomend extract` on every slice source of gen_stacks.py.

Usage: test_cli_io.py ISOMEND_CLI STACKS_DIR [NRRD_TO_TIFF_SLICES_PY]

- every bad stack: exit status 1, the message names the file and the reason,
  and no output file (nor a temporary one) is left in the output folder;
- every good stack: `info --json` reports its dimensions, type, kind and
  spacing; the mesh extracted from the stack is byte-identical to the mesh of
  the expected volume given as raw (same values, same order, same axes), and
  the same bytes again when --max-memory makes it stream the slices;
- without --iso, extract uses the suggested level and says so;
- `info` prints the histogram, the spacing with its origin and the suggested iso;
- the L phantom's mesh has the L where the image has it (not mirrored).
"""
import json
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

import numpy as np

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from clitest import check, failures, read_ply_arrays, run as run_cli  # noqa: E402

CLI, STACKS = sys.argv[1], os.path.abspath(sys.argv[2])


def run(args):
    return run_cli(CLI, args)


def stack_args(channel, first, count, step):
    a = []
    if channel == -2:
        a += ["--channel", "luma"]
    elif channel >= 0:
        a += ["--channel", str(channel)]
    if first:
        a += ["--first", str(first)]
    if count:
        a += ["--count", str(count)]
    if step != 1:
        a += ["--step", str(step)]
    return a


INFO_ERRORS = {"missing_in_list", "unknown_file", "deflate_corrupt", "size_mismatch", "volume3d",
               "one_slice_file", "too_large", "hyperstack"}
cases = [line.rstrip("\n").split("\t") for line in open(os.path.join(STACKS, "manifest.tsv"))]
with tempfile.TemporaryDirectory() as tmp:
    # ---- bad stacks: exit 1, message, nothing written ----
    def bad_case(f):
        name, sub = f[1], f[3]
        srcs = [os.path.join(STACKS, s) for s in f[8:]]
        opts = stack_args(int(f[4]), int(f[5]), int(f[6]), int(f[7]))
        outdir = os.path.join(tmp, "out_" + name)
        os.makedirs(outdir)
        r = run(["extract"] + srcs + opts + ["-o", os.path.join(outdir, "mesh.ply"), "--iso", "1"])
        check(r.returncode == 1, "%s: extract exit %d (want 1): %s" % (name, r.returncode, r.stderr))
        check(sub in r.stderr, "%s: extract message lacks %r: %s" % (name, sub, r.stderr))
        check(os.listdir(outdir) == [], "%s: extract left %s" % (name, os.listdir(outdir)))
        if name in INFO_ERRORS:  # `info` shares the code path: a sample of each kind of error
            r = run(["info"] + srcs + opts)
            check(r.returncode == 1, "%s: info exit %d (want 1)" % (name, r.returncode))
            # a volume larger than memory is analysed slice by slice by `info` (it holds no
            # mesh), so the stack whose pages have no data fails on its first missing page
            isub = "huge.tif (page " if name == "too_large" else sub
            check(isub in r.stderr, "%s: info message lacks %r: %s" % (name, isub, r.stderr))
        print("err  %-18s exit 1: %s" % (name, r.stderr.strip().splitlines()[-1] if r.stderr else ""))

    # two at a time: each run loads OpenImageIO (~0.3 s), the machine has 2 cores
    with ThreadPoolExecutor(2) as pool:
        list(pool.map(bad_case, [c for c in cases if c[0] == "err"]))

    # ---- good stacks: info, and mesh == mesh of the expected raw volume ----
    def good_case(f):
        name, tname, nx, ny, nz, exp, kind = f[1], f[2], int(f[3]), int(f[4]), int(f[5]), f[6], f[7]
        spacing = [float(x) for x in f[12:15]]
        srcs = [os.path.join(STACKS, s) for s in f[16:]]
        opts = stack_args(int(f[8]), int(f[9]), int(f[10]), int(f[11]))
        r = run(["info"] + srcs + opts + ["--json", "-"])
        check(r.returncode == 0, "%s: info exit %d: %s" % (name, r.returncode, r.stderr))
        if r.returncode:
            return
        info = json.loads(r.stdout)
        check(info["dims"] == [nx, ny, nz], "%s: dims %s" % (name, info["dims"]))
        check(info["type"] == tname, "%s: type %s" % (name, info["type"]))
        check(info["kind"] == kind, "%s: kind %s (want %s)" % (name, info["kind"], kind))
        if spacing[0] > 0:
            check(np.allclose(info["spacing"], spacing, rtol=1e-6), "%s: spacing %s" % (name, info["spacing"]))
            check(",".join(info["spacing_from"]) == f[15], "%s: spacing from %s" % (name, info["spacing_from"]))
        sp = spacing if spacing[0] > 0 else [1.0, 1.0, 1.0]
        dt = {"u8": "<u1", "i8": "<i1", "u16": "<u2", "i16": "<i2", "i32": "<i4", "f32": "<f4",
              "f64": "<f8"}[tname]
        vol = np.fromfile(os.path.join(STACKS, exp), dtype=dt)
        iso = float(np.median(vol)) + (0.5 if tname[0] in "ui" else 0.0)
        spacing_arg = ",".join(repr(s) for s in sp)
        a, b = os.path.join(tmp, name + "_stack.ply"), os.path.join(tmp, name + "_raw.ply")
        common = ["--iso", repr(iso), "--pad", "--quiet", "--spacing", spacing_arg, "--origin", "0,0,0"]
        ja = os.path.join(tmp, name + "_stack.json")
        r1 = run(["extract"] + srcs + opts + ["-o", a, "--json", ja, "--in-memory"] + common)
        r2 = run(["extract", os.path.join(STACKS, exp), "--raw", "%d,%d,%d:%s" % (nx, ny, nz, tname),
                  "-o", b, "--iso", repr(iso), "--pad", "--quiet", "--spacing", spacing_arg,
                  "--origin", "0,0,0"])
        check(r1.returncode == 0 and r2.returncode == 0, "%s: extract failed: %s %s" % (name, r1.stderr, r2.stderr))
        if r1.returncode == 0 and r2.returncode == 0:
            da, db = open(a, "rb").read(), open(b, "rb").read()
            body = lambda x: x[x.index(b"end_header\n"):]
            check(body(da) == body(db), "%s: the stack's mesh differs from the raw volume's" % name)
            # streamed (the default; slices read one by one through isomend_io_read_slice):
            # the same bytes and the same continuity check
            j = json.load(open(ja))
            c = os.path.join(tmp, name + "_streamed.ply")
            r3 = run(["extract"] + srcs + opts + ["-o", c, "--json", "-"] + common)
            check(r3.returncode == 0, "%s: streamed extract failed: %s" % (name, r3.stderr))
            if r3.returncode == 0:
                js = json.loads(r3.stdout)
                check(js["streamed"] and not js["volume_loaded"] and not j["streamed"],
                      "%s: streamed flags %s / %s" % (name, js["streamed"], j["streamed"]))
                check(js["check"] == j["check"] and j["check"] is not None,
                      "%s: the streamed check differs: %s vs %s" % (name, js["check"], j["check"]))
                check(open(c, "rb").read() == da, "%s: the streamed stack's mesh differs" % name)
            print("ok   %-18s info %s %s %s; mesh at iso %g equals the raw volume's and streamed (%d bytes)"
                  % (name, kind, tname, info["dims"], iso, len(da)))

    with ThreadPoolExecutor(2) as pool:
        list(pool.map(good_case, [c for c in cases if c[0] == "ok"]))

    # ---- suggested iso, info text, --json timing ----
    src = os.path.join(STACKS, "bimodal")
    r = run(["extract", src, "-o", os.path.join(tmp, "bimodal.ply"), "--json", "-"])
    check(r.returncode == 0, "bimodal extract: " + r.stderr)
    j = json.loads(r.stdout)
    check(j["iso_suggested"] and 23 < j["iso"] < 197, "bimodal: iso %s" % j["iso"])
    check("suggested" in r.stderr, "extract does not say it used the suggested level: " + r.stderr)
    check(j["timings_ms"]["read"] >= 0, "extract --json lacks the read timing")
    r = run(["info", os.path.join(STACKS, "multipage", "stack.tif")])
    check(r.returncode == 0 and "histogram" in r.stdout and "imagej" in r.stdout
          and "suggested iso" in r.stdout, "info text: " + r.stdout)
    print(r.stdout)

    # ---- the L phantom, through the command line ----
    out = os.path.join(tmp, "L.ply")
    r = run(["extract", os.path.join(STACKS, "L_phantom"), "-o", out, "--iso", "50", "--pad", "--quiet"])
    check(r.returncode == 0, "L extract: " + r.stderr)
    v, _ = read_ply_arrays(out)
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    foot = (y > 10.4) & (y < 12.6) & (x > 8.4)           # the foot: bottom right of the image
    mirrored = ((y < 10.4) & (y > 4.6) & (x > 4.6)) | (y < 1.4) | (x > 10.6) | (y > 13.6)
    dot = (x > 7.4) & (y < 4.6)
    check(foot.sum() > 0 and mirrored.sum() == 0, "L phantom: foot %d, at mirrored places %d"
          % (foot.sum(), mirrored.sum()))
    check(dot.sum() > 0 and z[dot].max() < 1.6, "L phantom: the dot of slice 1 is not in slice 1")
    print("ok   L phantom: %d vertices at the foot (bottom right), none at mirrored places" % foot.sum())

    # ---- io/slices/tools/nrrd_to_tiff_slices.py (used by scripts/demo.sh) ----
    if len(sys.argv) > 3:
        for nrrd in ("vol.nrrd", "vol_gz.nrrd"):
            folder = os.path.join(tmp, "slices_" + nrrd.replace(".", "_"))
            r = subprocess.run([sys.executable, sys.argv[3], os.path.join(STACKS, "nrrd", nrrd), folder],
                               capture_output=True, text=True)
            check(r.returncode == 0, "nrrd_to_tiff_slices %s: %s" % (nrrd, r.stderr))
            a, b = os.path.join(tmp, "n1.ply"), os.path.join(tmp, "n2.ply")
            r1 = run(["extract", os.path.join(STACKS, "nrrd", nrrd), "-o", a, "--iso", "1000.5", "--quiet"])
            r2 = run(["extract", folder, "-o", b, "--iso", "1000.5", "--quiet", "--json", "-"])
            check(r1.returncode == 0 and r2.returncode == 0, "tool round trip: %s %s" % (r1.stderr, r2.stderr))
            if r2.returncode == 0:
                j = json.loads(r2.stdout)
                want_sp = [0.5, 0.75, 2.0] if nrrd == "vol.nrrd" else [1.0, 1.0, 1.0]
                check(np.allclose(j["spacing"], want_sp, rtol=1e-6), "tool spacing %s" % j["spacing"])
                da, db = open(a, "rb").read(), open(b, "rb").read()
                check(da[da.index(b"end_header"):] == db[db.index(b"end_header"):],
                      "%s: mesh from the tool's TIFF slices differs from the NRRD's" % nrrd)
                print("ok   nrrd_to_tiff_slices.py %s: same mesh from the slices as from the NRRD" % nrrd)

if failures:
    print("%d failure(s)" % len(failures))
    sys.exit(1)
print("ok")
