#!/usr/bin/env python3
"""`isomend extract`: the streamed path (the default) writes the in-memory path's bytes.

For every kind of raw/NRRD source (raw little and big endian, NRRD attached,
detached with byte and line skips, gzip with several members, reversed axes,
built-in F1, the bundled MRI, a gyroid and smoothed noise) and PLY, OBJ and
STL with several option sets (default, --pad, --no-normals --flip, every
method), the mesh written when `--max-memory` makes the stream read the
volume slice by slice is identical byte for byte to the one of the
in-memory path (`--in-memory`), and the continuity check made as the mesh
went by reports exactly what the in-memory check reports.  The JSON says
which path ran (`streamed`) and the peak memory.

Errors: bad --max-memory values are usage errors naming the flag; a limit
below what streaming needs is refused; a gzip volume with a reversed z axis
cannot be streamed and says so; a write failure (the file size limit) and
Ctrl-C while streaming leave no output, temporary or scratch file.

Memory: `isomend info` streams a volume larger than --max-memory for real
(it holds no mesh): its peak memory must stay far below the volume's size.
The extraction's peak under --max-memory is cli_stream_memory's
(test_stream_memory.py).

usage: test_stream.py --isomend PATH --samples DIR --work DIR
"""
import argparse
import gzip
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import clitest  # noqa: E402
from clitest import fail  # noqa: E402

MEMORY_BOUNDS = True


def run(exe, args, cwd, preexec=None, timeout=300):
    p = subprocess.run([exe, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                       stdin=subprocess.DEVNULL, preexec_fn=preexec)
    return p.returncode, p.stdout, p.stderr


def entries(folder):
    return sorted(os.listdir(folder))


# ------------------------------------------------------------------ volumes

def nrrd_header(arr, encoding, endian="little", extra=""):
    t = {"uint8": "uint8", "int8": "int8", "uint16": "uint16", "int16": "int16",
         "int32": "int32", "float32": "float", "float64": "double"}[arr.dtype.name]
    nz, ny, nx = arr.shape
    return (f"NRRD0004\ntype: {t}\ndimension: 3\nsizes: {nx} {ny} {nz}\nendian: {endian}\n"
            f"encoding: {encoding}\n{extra}")


def write_nrrd(path, arr, encoding="raw", endian="little", extra="", members=1):
    data = arr.astype(arr.dtype.newbyteorder("<" if endian == "little" else ">")).tobytes()
    with open(path, "wb") as f:
        f.write((nrrd_header(arr, encoding, endian, extra) + "\n").encode())
        if encoding == "raw":
            f.write(data)
        else:
            cut = [len(data) * i // members for i in range(members + 1)]
            for a, b in zip(cut, cut[1:]):
                f.write(gzip.compress(data[a:b], 6))


def sphere(n=(34, 30, 40), dtype=np.float32):
    z, y, x = np.mgrid[0:n[2], 0:n[1], 0:n[0]].astype(np.float64)
    r = np.sqrt((x - n[0] / 2.3) ** 2 + (y - n[1] / 1.9) ** 2 + (z - n[2] / 2.1) ** 2)
    return (20.0 - r).astype(dtype)


def gyroid(n=48):
    z, y, x = np.mgrid[0:n, 0:n, 0:n].astype(np.float64) * (2 * np.pi / 17)
    return (np.sin(x) * np.cos(y) + np.sin(y) * np.cos(z) + np.sin(z) * np.cos(x)).astype(np.float32)


def noise(shape=(40, 33, 29), seed=7):
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 4000, size=shape).astype(np.float64)
    for ax in range(3):  # a few box filters: blobs of every topology
        a = (a + np.roll(a, 1, ax) + np.roll(a, -1, ax)) / 3
    return a.astype(np.uint16)


def make_sources(work, samples):
    """[(name, args, iso)]: every kind of raw/NRRD source."""
    src = []
    s = sphere()
    s.tofile(os.path.join(work, "sphere.raw"))
    src.append(("raw_f32", ["sphere.raw", "--raw", "34,30,40:f32"], "0.5"))
    n = noise()
    n.astype(">u2").tofile(os.path.join(work, "noise_be.raw"))
    src.append(("raw_u16_be", ["noise_be.raw", "--raw", "29,33,40:u16:be"], "2000.5"))
    write_nrrd(os.path.join(work, "noise.nrrd"), n.astype(np.int16), "raw", "big")
    src.append(("nrrd_i16_big", ["noise.nrrd"], "1990.5"))
    write_nrrd(os.path.join(work, "noise_gz.nrrd"), n, "gzip", members=3)
    src.append(("nrrd_gzip_members", ["noise_gz.nrrd"], "2010.5"))
    write_nrrd(os.path.join(work, "gyroid_gz.nrrd"), gyroid(), "gzip",
               extra="spacings: 0.5 0.75 1.25\nspace origin: (1,2,3)\n")
    src.append(("nrrd_gzip_gyroid", ["gyroid_gz.nrrd"], "0.1"))
    # detached, one line and 5 bytes skipped
    u8 = (sphere(dtype=np.float64) * 6 + 100).clip(0, 255).astype(np.uint8)
    with open(os.path.join(work, "det.data"), "wb") as f:
        f.write(b"a skipped line\nSKIP!" + u8.tobytes())
    with open(os.path.join(work, "det.nhdr"), "w") as f:
        f.write(nrrd_header(u8, "raw") + "line skip: 1\nbyte skip: 5\ndata file: det.data\n")
    src.append(("nhdr_skips_u8", ["det.nhdr"], "120.5"))
    # reversed axes (RAS data): raw may reverse any axis, gzip only x and y
    dirs = "space directions: (-1,0,0) (0,-1.5,0) (0,0,-2)\nspace origin: (10,20,30)\n"
    write_nrrd(os.path.join(work, "rev.nrrd"), s, "raw", extra=dirs)
    src.append(("nrrd_reversed_xyz", ["rev.nrrd"], "0.5"))
    dirs_xy = "space directions: (-1,0,0) (0,-1.5,0) (0,0,2)\n"
    write_nrrd(os.path.join(work, "rev_gz.nrrd"), n.astype(np.float64), "gzip", extra=dirs_xy)
    src.append(("nrrd_gzip_reversed_xy", ["rev_gz.nrrd"], "2000"))
    src.append(("builtin_f1", ["builtin:f1"], "0"))
    src.append(("mri", [os.path.join(samples, "anatomical.nrrd")], None))  # suggested iso
    return src


# ------------------------------------------------------------------ byte identity

def estimates(exe, work, args):
    """(in-memory estimate, streaming need) from a run that reports them."""
    rc, out, err = run(exe, ["extract", *args, "-o", "probe.ply", "--json", "-", "-q"], work)
    os.unlink(os.path.join(work, "probe.ply")) if rc == 0 else None
    if rc != 0:
        return None
    j = json.loads(out)
    return j["memory_estimate"], j["memory_streaming"]


def test_same_bytes(exe, work, samples):
    methods = []
    rc, out, _ = run(exe, ["--version"], work)
    for m in ("mc", "durst", "dmc", "facial", "gradient", "asymptotic", "tetra", "mc33"):
        if f" {m}" in out.split("(methods:")[1].split(";")[0] + " ":
            methods.append(m)
    option_sets = [[], ["--pad"], ["--no-normals", "--flip"]]
    pairs = 0
    for name, args, iso in make_sources(work, samples):
        method_sources = ("raw_f32", "nrrd_gzip_members", "mri") if MEMORY_BOUNDS else ("raw_f32",)
        sets = option_sets + ([["--method", m, "--pad"] for m in methods]
                              if name in method_sources else [])
        for fmt in ("ply", "obj", "stl"):
            for opts in sets:
                base = args + (["--iso", iso] if iso else []) + opts + ["-q"]
                est = estimates(exe, work, base)
                if est is None:
                    fail(name, "the in-memory run failed")
                    continue
                limit = str((est[0] + est[1]) // 2)  # between: streams, and streaming fits
                a, b = f"mem.{fmt}", f"streamed.{fmt}"
                rc1, out1, err1 = run(exe, ["extract", *base, "-o", a, "--json", "mem.json",
                                            "--in-memory"], work)
                rc2, out2, err2 = run(exe, ["extract", *base, "-o", b, "--json", "str.json",
                                            "--max-memory", limit], work)
                label = f"{name} {fmt} {' '.join(opts) or 'default'}"
                if rc1 or rc2:
                    fail(label, f"exit {rc1}/{rc2}: {err1.strip()} {err2.strip()}")
                    continue
                ja = json.load(open(os.path.join(work, "mem.json")))
                jb = json.load(open(os.path.join(work, "str.json")))
                if ja["streamed"] or not jb["streamed"]:
                    fail(label, f"streamed {ja['streamed']} / {jb['streamed']}")
                if ja["check"] is None or jb["check"] != ja["check"]:
                    fail(label, f"the streamed check {jb['check']} is not the in-memory one "
                                f"{ja['check']}")
                if jb["memory_limit"] != int(limit) or jb["memory_limit_from"] != "option":
                    fail(label, f"limit {jb['memory_limit']} from {jb['memory_limit_from']}")
                if not (jb["peak_memory"] > 0 and ja["peak_memory"] > 0):
                    fail(label, "no peak memory")
                for k in ("vertices", "triangles", "iso", "case_histogram", "triangles_by_origin"):
                    if ja[k] != jb[k]:
                        fail(label, f"{k}: {ja[k]} vs {jb[k]}")
                da = open(os.path.join(work, a), "rb").read()
                db = open(os.path.join(work, b), "rb").read()
                if da != db:
                    fail(label, f"streamed mesh differs ({len(da)} vs {len(db)} bytes)")
                if fmt == "ply" and not opts:  # a pool of 3 (the default takes cores - 1)
                    c = "pool.ply"
                    rc3, _, err3 = run(exe, ["extract", *base, "-o", c, "--json", "pool.json",
                                             "--threads", "3"], work)
                    jc = json.load(open(os.path.join(work, "pool.json"))) if rc3 == 0 else {}
                    if rc3 or not jc["streamed"] or jc["stream_threads"] != 3 or jc["check"] != ja["check"]:
                        fail(label, f"--threads 3: exit {rc3} {err3.strip()}, streamed "
                                    f"{jc.get('streamed')}, threads {jc.get('stream_threads')}, "
                                    f"check {jc.get('check')}")
                    elif open(os.path.join(work, c), "rb").read() != da:
                        fail(label, "--threads 3: the streamed mesh differs")
                    for f in (c, "pool.json"):
                        if os.path.exists(os.path.join(work, f)):
                            os.unlink(os.path.join(work, f))
                elif ja["triangles"] == 0 and name != "builtin_f1":
                    fail(label, "empty mesh: the comparison proves little")
                pairs += 1
                for f in (a, b, "mem.json", "str.json"):
                    os.unlink(os.path.join(work, f))
    left = [e for e in entries(work) if ".tmp" in e or ".spool" in e]
    if left:
        fail("same bytes", f"left behind: {left}")
    print(f"ok   {pairs} streamed meshes equal the in-memory ones byte for byte")


# ------------------------------------------------------------------ errors

def expect_error(exe, work, name, args, code, subs, pre=None):
    out_dir = os.path.join(work, "err_" + name.replace(" ", "_"))
    os.makedirs(out_dir, exist_ok=True)
    rc, out, err = run(exe, [a.replace("OUT/", out_dir + "/") for a in args], work, pre)
    if rc != code:
        fail(name, f"exit {rc}, expected {code}: {err.strip()}")
    for s in subs:
        if s not in err:
            fail(name, f"message {err.strip()!r} lacks {s!r}")
    if entries(out_dir):
        fail(name, f"left behind: {entries(out_dir)}")
    shutil.rmtree(out_dir)
    return err


def test_errors(exe, work):
    for bad in ("abc", "0", "-5", "1.5", "12X", "4GG", "", "1e30T"):
        expect_error(exe, work, f"bad size {bad!r}",
                     ["extract", "builtin:f1", "--iso", "0", "-o", "OUT/m.ply", "--max-memory", bad],
                     2, ["--max-memory"])
    for good in ("512M", "4G", "1.5G", "1073741824", "2GiB", "3gb"):
        rc, out, err = run(exe, ["extract", "builtin:f1", "--iso", "0", "-o", "ok.ply", "-q",
                                 "--max-memory", good, "--json", "-"], work)
        if rc or json.loads(out)["memory_limit"] <= 0:
            fail(f"size {good}", f"exit {rc}: {err.strip()}")
        os.unlink(os.path.join(work, "ok.ply")) if rc == 0 else None
    # a limit below what streaming needs
    expect_error(exe, work, "limit too small",
                 ["extract", "sphere.raw", "--raw", "34,30,40:f32", "--iso", "0.5", "-o",
                  "OUT/m.ply", "--max-memory", "1M"], 2, ["--max-memory", "streaming", "sphere.raw"])
    # gzip whose z axis is reversed: fine in memory, refused when streamed
    write_nrrd(os.path.join(work, "rev_z_gz.nrrd"), sphere(), "gzip",
               extra="space directions: (1,0,0) (0,1,0) (0,0,-1)\n")
    rc, _, err = run(exe, ["extract", "rev_z_gz.nrrd", "--iso", "0.5", "-o", "revz.ply", "-q"], work)
    if rc:
        fail("gzip reversed z in memory", err.strip())
    else:
        os.unlink(os.path.join(work, "revz.ply"))
    # ... loaded (then streamed) when the volume fits beside the stream, refused when it does not
    est = estimates(exe, work, ["rev_z_gz.nrrd", "--iso", "0.5"])
    rc, out, err = run(exe, ["extract", "rev_z_gz.nrrd", "--iso", "0.5", "-o", "revz.ply", "-q",
                             "--max-memory", str((est[0] + est[1]) // 2), "--json", "-"], work)
    if rc or not json.loads(out)["volume_loaded"]:
        fail("gzip reversed z loaded", err.strip() or "not loaded")
    else:
        os.unlink(os.path.join(work, "revz.ply"))
    expect_error(exe, work, "gzip reversed z streamed",
                 ["extract", "rev_z_gz.nrrd", "--iso", "0.5", "-o", "OUT/m.ply", "--max-memory",
                  str(est[1] + 1024)], 1, ["rev_z_gz.nrrd", "reverse the z axis", "raw"])

    # the file size limit hit while streaming (faces spooled, vertices written)
    g = gyroid(96)
    g.tofile(os.path.join(work, "g96.raw"))
    args = ["g96.raw", "--raw", "96,96,96:f32", "--iso", "0.1"]
    est = estimates(exe, work, args)
    limit = str((est[0] + est[1]) // 2)

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_DFL)  # isomend ignores it itself
        resource.setrlimit(resource.RLIMIT_FSIZE, (256 * 1024, resource.RLIM_INFINITY))
    for fmt in ("ply", "obj", "stl"):
        expect_error(exe, work, f"write failure {fmt}",
                     ["extract", *args, "-o", f"OUT/m.{fmt}", "--max-memory", limit, "-q"], 1,
                     [f"m.{fmt}", "write failed"], pre=small_files)
    print("ok   errors: sizes, a too small limit, gzip reversed z, write failures")


def test_interrupt(exe, work):
    """SIGINT while streaming: exit 130 and nothing, or done and complete.  A
    160^3 gyroid streams for about 100 ms or more (a 96^3 one could end before the
    first signal on a fast machine)."""
    gyroid(160).tofile(os.path.join(work, "g160.raw"))
    args = ["g160.raw", "--raw", "160,160,160:f32", "--iso", "0.1"]
    est = estimates(exe, work, args)
    limit = str((est[0] + est[1]) // 2)
    outcomes = set()
    for delay in (0.01, 0.03, 0.08, 0.2):
        out_dir = os.path.join(work, "intr")
        os.makedirs(out_dir, exist_ok=True)
        p = subprocess.Popen([exe, "extract", *args, "-o", os.path.join(out_dir, "m.ply"), "-q",
                              "--max-memory", limit], cwd=work, stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True)
        time.sleep(delay)
        p.send_signal(signal.SIGINT)
        err = p.communicate(timeout=120)[1]
        left = entries(out_dir)
        if p.returncode == 130:
            if left or "interrupted" not in err:
                fail(f"interrupt {delay}", f"left {left}; {err.strip()}")
        elif p.returncode == 0:
            if left != ["m.ply"]:
                fail(f"interrupt {delay}", f"finished but left {left}")
        elif p.returncode == -signal.SIGINT:  # before main() installed its handler
            if left:
                fail(f"interrupt {delay}", f"killed at start-up but left {left}")
        else:
            fail(f"interrupt {delay}", f"exit {p.returncode}: {err.strip()}")
        outcomes.add(p.returncode)
        shutil.rmtree(out_dir)
    os.unlink(os.path.join(work, "g160.raw"))
    if 130 not in outcomes:
        fail("interrupt", "no run was interrupted (all finished before the signal)")
    print(f"ok   Ctrl-C while streaming: exits {sorted(outcomes)}, nothing partial left")


def test_info_memory(exe, work):
    """`info` on a volume 16x its --max-memory holds a few slices, not the volume."""
    z, y, x = np.mgrid[0:512, 0:256, 0:256].astype(np.float32)
    vol = (30000 + 20000 * np.sin(x / 9) * np.cos(y / 13) * np.sin(z / 7)).astype(np.uint16)  # 64 MiB
    write_nrrd(os.path.join(work, "big_gz.nrrd"), vol, "gzip")
    vol.tofile(os.path.join(work, "big.raw"))
    del vol, x, y, z
    for name, args in (("gzip", ["big_gz.nrrd"]), ("raw", ["big.raw", "--raw", "256,256,512:u16"])):
        rc, out, err = run(exe, ["info", *args, "--json", "-", "--max-memory", "4M"], work)
        rc2, out2, err2 = run(exe, ["info", *args, "--json", "-"], work)
        if rc or rc2:
            fail(f"info memory {name}", f"{err.strip()} {err2.strip()}")
            continue
        a, b = json.loads(out), json.loads(out2)
        if not a["streamed"] or b["streamed"]:
            fail(f"info memory {name}", f"streamed {a['streamed']} / {b['streamed']}")
        for k in ("min", "max", "histogram", "suggested_iso", "samples", "nan_samples"):
            if a[k] != b[k]:
                fail(f"info memory {name}", f"{k}: {a[k]} vs {b[k]}")
        mib = 1024 * 1024
        # the volume is 64 MiB: loaded, the peak exceeds it; streamed, it stays a few slices
        if MEMORY_BOUNDS and not (b["peak_memory"] > 64 * mib and a["peak_memory"] < 16 * mib):
            fail(f"info memory {name}", f"peak {a['peak_memory'] / mib:.1f} MiB streamed, "
                                        f"{b['peak_memory'] / mib:.1f} MiB loaded")
        print(f"ok   info {name} 64 MiB volume: peak {a['peak_memory'] / mib:.1f} MiB streamed, "
              f"{b['peak_memory'] / mib:.1f} MiB loaded, same summary")
    for f in ("big_gz.nrrd", "big.raw"):
        os.unlink(os.path.join(work, f))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--samples", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--no-memory-bounds", action="store_true",
                    help="sanitizer builds: no peak memory asserted (the shadow memory counts), "
                         "every method on one source instead of three")
    a = ap.parse_args()
    global MEMORY_BOUNDS
    MEMORY_BOUNDS = not a.no_memory_bounds
    exe = os.path.abspath(a.isomend)
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    test_same_bytes(exe, a.work, os.path.abspath(a.samples))
    test_errors(exe, a.work)
    test_interrupt(exe, a.work)
    test_info_memory(exe, a.work)
    return clitest.summary()


if __name__ == "__main__":
    sys.exit(main())
