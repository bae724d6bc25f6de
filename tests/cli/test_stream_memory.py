#!/usr/bin/env python3
"""`isomend extract --max-memory SIZE` meshes a stack several times SIZE within SIZE.

A 512 x 512 x 384 u16 volume with a busy, smooth surface (29 M triangles),
as raw samples and as a folder of 384 TIFF slices (when the importer is
built), is extracted three ways:

- in memory (--in-memory), without a limit: the peak resident memory
  measured here (the child's ru_maxrss from os.wait4) must be at least 8 x SIZE;
- with --max-memory SIZE, PLY and STL: the run streams, writes the in-memory
  run's bytes, and its peak, measured the same way, is within SIZE plus the
  program's fixed overhead, which is measured too: the peak of the same
  program on the first two slices of the same source (its code, libraries
  and their heaps; OpenImageIO's are about 130 MiB, raw reading's a few);
  peaks are wait4's ru_maxrss, through tests/common/peak_rss.c;
  and within the streaming bound it reports (`memory_streaming`) plus that
  overhead; the continuity check's own tables and queue at their largest
  (JSON `check_memory.peak`) within what the plan counted for them
  (`check_memory.planned`);
- streamed again on the first 64 slices: the peak does not depend on the
  number of slices (within 4 MiB).

And the in-memory path (--in-memory) under a limit: with a SIZE that holds the volume and
the mesh (the in-memory estimate plus 64 MiB), the continuity check runs too (an extracted
mesh is checked in its order, holding a window of a few slices' vertices: about 4 bytes a
vertex, where sorting its edges took 52 a triangle and 37 a vertex, and the check was
skipped there), the mesh is the same, and the peak stays within SIZE plus the overhead.

And 64-bit indices end to end: a thin, tall raw volume of 2^31 + 8192 samples
(a sparse file) with a surface at both ends, streamed and in memory, gives the
same file, and the top surface's vertices are in it.

Not for the sanitizers (their shadow memory counts as resident).

usage: test_stream_memory.py --isomend PATH --peak-rss PATH --work DIR
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

PEAK_RSS = None
MIB = 1024 * 1024
NX, NY, NZ = 512, 512, 384
ISO = "1000"


def run_measured(args, cwd):
    return clitest.run_measured(PEAK_RSS, args, cwd)


def field(k):
    return clitest.busy_slice(k, NX, NY)


def make_sources(work, with_tiff):
    """raw volumes of NZ, 64 and 2 slices, and the same as TIFF folders."""
    sources = {}
    folders = {n: os.path.join(work, f"tif{n}") for n in (NZ, 64, 2)}
    if with_tiff:
        import tifffile
        for d in folders.values():
            os.makedirs(d)
    with open(os.path.join(work, "v.raw"), "wb") as f:
        for k in range(NZ):
            a = field(k)
            f.write(a.tobytes())
            for n, d in folders.items():
                if with_tiff and k < n:
                    tifffile.imwrite(os.path.join(d, f"s_{k:04d}.tif"), a)
    with open(os.path.join(work, "v.raw"), "rb") as f:
        head = f.read(64 * NX * NY * 2)
    with open(os.path.join(work, "v64.raw"), "wb") as g:
        g.write(head)
    with open(os.path.join(work, "v2.raw"), "wb") as g:
        g.write(head[:2 * NX * NY * 2])
    sources["raw"] = {n: [f"v{'' if n == NZ else n}.raw", "--raw", f"{NX},{NY},{n}:u16"]
                      for n in (NZ, 64, 2)}
    if with_tiff:
        sources["tiff"] = {n: [folders[n]] for n in (NZ, 64, 2)}
    return sources


def extract(exe, work, src, out, extra=()):
    args = [exe, "extract", *src, "--iso", ISO, "-o", out, "-q", "--json", "j.json", *extra]
    rc, _, err, peak = run_measured(args, work)
    js = None
    if rc == 0:
        with open(os.path.join(work, "j.json")) as f:
            js = json.load(f)
    return rc, err, peak, js


same_file = clitest.same_file


def check_kind(exe, work, kind, src, size):
    name = f"{kind}"
    # the program's fixed overhead: the same source kind, two slices
    rc, err, overhead, _ = extract(exe, work, src[2], "tiny.ply", ["--max-memory", size])
    if rc:
        fail(f"{name} overhead", err.strip())
        return
    os.unlink(os.path.join(work, "tiny.ply"))
    limit = int(size[:-1]) * MIB
    for fmt in ("ply", "stl"):
        whole, part = f"mem.{fmt}", f"streamed.{fmt}"
        rc, err, peak_mem, jm = extract(exe, work, src[NZ], whole, ["--in-memory"])
        if rc:
            fail(f"{name} {fmt} in memory", err.strip())
            continue
        rc, err, peak, js = extract(exe, work, src[NZ], part, ["--max-memory", size])
        if rc:
            fail(f"{name} {fmt} streamed", err.strip())
            continue
        label = (f"{name} {fmt}: {jm['triangles']} triangles, in memory {peak_mem / MIB:.1f} MiB "
                 f"({peak_mem / limit:.1f}x --max-memory {size}), streamed {peak / MIB:.1f} MiB "
                 f"(bound {js['memory_streaming'] / MIB:.1f} MiB + overhead {overhead / MIB:.1f} MiB)")
        if jm["streamed"] or not js["streamed"]:
            fail(label, f"streamed: {jm['streamed']} without the limit, {js['streamed']} with it")
        if peak_mem < 8 * limit:
            fail(label, "the in-memory run does not need 8x the limit: the test proves nothing")
        if jm["memory_estimate"] < 4 * limit:
            fail(label, f"in-memory estimate {jm['memory_estimate'] / MIB:.1f} MiB below 4x the limit")
        if peak > limit + overhead:
            fail(label, "streamed peak beyond --max-memory plus the fixed overhead")
        if peak > js["memory_streaming"] + overhead:
            fail(label, "streamed peak beyond the reported streaming bound plus the overhead")
        cm = js.get("check_memory")  # the check's tables and queue: within what the plan counted
        if js["check"] is None:  # (STL's kept positions leave it no room under this limit)
            if cm is not None or js["check_skipped"] != "memory":
                fail(label, f"unchecked, yet check_memory {cm}, check_skipped {js['check_skipped']}")
            else:
                label += "; check skipped (memory)"
        elif not cm or cm["peak"] > cm["planned"]:
            fail(label, f"the streamed check's memory {cm} beyond what the plan counted for it")
        else:
            label += f"; check {cm['peak'] / MIB:.1f} of {cm['planned'] / MIB:.1f} MiB planned"
        if not same_file(os.path.join(work, whole), os.path.join(work, part)):
            fail(label, "the streamed mesh differs from the in-memory one")
        # peak independent of the number of slices
        rc, err, peak64, _ = extract(exe, work, src[64], f"s64.{fmt}", ["--max-memory", size])
        if rc:
            fail(f"{name} {fmt} 64 slices", err.strip())
        elif abs(peak - peak64) > 4 * MIB:
            fail(label, f"peak {peak / MIB:.1f} MiB at {NZ} slices, {peak64 / MIB:.1f} MiB at 64")
        else:
            label += f"; 64 slices {peak64 / MIB:.1f} MiB"
        for f in (whole, part, f"s64.{fmt}"):
            if os.path.exists(os.path.join(work, f)):
                os.unlink(os.path.join(work, f))
        if not clitest.failed(label):
            print(f"ok   {label}")


def check_in_memory_limit(exe, work, src):
    """A limit that holds the in-memory extraction holds its check: checked, within it."""
    rc, err, peak_free, jm = extract(exe, work, src[NZ], "free.ply", ["--in-memory"])
    if rc:
        fail("in memory under a limit", err.strip())
        return
    rc, err, overhead, _ = extract(exe, work, src[2], "tiny.ply", ["--in-memory"])
    sorted_need = 52 * jm["triangles"] + 37 * jm["vertices"]
    # the in-memory estimate fits with 64 MiB to spare; sorting the edges would not
    size_mib = int((jm["memory_estimate"] + 64 * MIB) / MIB)
    size = f"{size_mib}M"
    rc, err, peak, js = extract(exe, work, src[NZ], "limited.ply",
                                ["--max-memory", size, "--in-memory"])
    label = (f"in memory under --max-memory {size}: peak {peak / MIB:.1f} MiB "
             f"(without a limit {peak_free / MIB:.1f} MiB; sorting the edges would need "
             f"~{sorted_need / MIB:.0f} MiB)")
    if rc:
        fail(label, err.strip())
        return
    if sorted_need < 64 * MIB:
        fail(label, "the sorted check would fit too: the test proves nothing")
    if js["streamed"] or js["check"] is None or js["check_skipped"] is not None:
        fail(label, f"streamed {js['streamed']}, check_skipped {js['check_skipped']}")
    elif js["check"]["holes"] != 0 or js["check"] != jm["check"]:
        fail(label, f"check {js['check']} against {jm['check']} without a limit")
    if jm["check"] is None or jm["check_skipped"] is not None:
        fail(label, "the run without a limit was not checked")
    if peak > size_mib * MIB + overhead:
        fail(label, "peak beyond the limit plus the overhead")
    if not same_file(os.path.join(work, "free.ply"), os.path.join(work, "limited.ply")):
        fail(label, "the meshes differ")
    for f in ("free.ply", "limited.ply", "tiny.ply"):
        if os.path.exists(os.path.join(work, f)):
            os.unlink(os.path.join(work, f))
    if not clitest.failed(label):
        print(f"ok   {label}")


def check_tall(exe, work):
    """64 x 64 x (2^19 + 2) u8: 2^31 + 8192 samples, a surface at both ends; streamed
    (--max-memory 64M) and in memory write the same bytes, the top's vertices are there."""
    nx = ny = 64
    nz = (1 << 19) + 2
    path = os.path.join(work, "tall.raw")
    plane = nx * ny
    y, x = np.mgrid[0:ny, 0:nx]
    blob = np.zeros((8, ny, nx), np.uint8)
    for k in range(8):
        blob[k] = np.where((x - 30) ** 2 + (y - 33) ** 2 + (k - 3.5) ** 2 * 9 < 400, 200, 0)
    with open(path, "wb") as f:  # sparse: zeros cost no disk
        f.truncate(nz * plane)
        f.seek(2 * plane)
        f.write(blob.tobytes())
        f.seek((nz - 9) * plane)
        f.write(blob.tobytes())
    src = [path, "--raw", f"{nx},{ny},{nz}:u8"]
    results = {}
    # the in-memory run touches 2 GiB; its estimate (15 GiB, a mesh of 6.25 bytes a sample)
    # must not exceed the limit, so it is given rather than left to MemAvailable
    for name, extra in (("streamed", ["--max-memory", "64M"]),
                        ("in memory", ["--max-memory", "32G", "--in-memory"])):
        args = [exe, "extract", *src, "--iso", "100", "-o", f"tall_{name[:2]}.ply", "-q",
                "--json", "j.json", *extra]
        rc, _, err, peak = run_measured(args, work)
        if rc:
            fail(f"tall {name}", err.strip())
            return
        with open(os.path.join(work, "j.json")) as f:
            results[name] = (json.load(f), peak)
    js, peak = results["streamed"]
    jm, peak_mem = results["in memory"]
    label = (f"tall 64 x 64 x {nz} u8 ({nx * ny * nz} samples > 2^31): {js['triangles']} "
             f"triangles, streamed peak {peak / MIB:.1f} MiB, in memory {peak_mem / MIB:.1f} MiB")
    if not js["streamed"] or jm["streamed"]:
        fail(label, f"streamed {js['streamed']} / {jm['streamed']}")
    if not same_file(os.path.join(work, "tall_st.ply"), os.path.join(work, "tall_in.ply")):
        fail(label, "the streamed mesh differs from the in-memory one")
    if jm["check"] is None or not (jm["check"]["continuous"] and jm["check"]["components"] == 2):
        fail(label, f"in-memory check: {jm['check']}")
    if js["check"] != jm["check"]:
        fail(label, f"the streamed check {js['check']} is not the in-memory one")
    # the top blob's vertices sit above z = 2^19 (positions are float32: exact at this size)
    with open(os.path.join(work, "tall_st.ply"), "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    verts = np.frombuffer(data, dtype="<f4", count=js["vertices"] * 6, offset=end).reshape(-1, 6)
    if not (verts[:, 2].max() > nz - 10 and verts[:, 2].min() < 12):
        fail(label, f"z range {verts[:, 2].min()} .. {verts[:, 2].max()}")
    for f in ("tall.raw", "tall_st.ply", "tall_in.ply"):
        os.unlink(os.path.join(work, f))
    if not clitest.failed(label):
        print(f"ok   {label}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--peak-rss", required=True, help="tests/common/peak_rss.c, built")
    a = ap.parse_args()
    global PEAK_RSS
    PEAK_RSS = os.path.abspath(a.peak_rss)
    exe = os.path.abspath(a.isomend)
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    version = subprocess.run([exe, "--version"], capture_output=True, text=True).stdout
    with_tiff = "slice-stack importer: yes" in version
    sources = make_sources(a.work, with_tiff)
    for kind, src in sources.items():
        check_kind(exe, a.work, kind, src, "96M")
    if not with_tiff:
        print("skip tiff: the importer is not built")
    check_in_memory_limit(exe, a.work, sources["raw"])
    check_tall(exe, a.work)
    shutil.rmtree(a.work, ignore_errors=True)
    return clitest.summary()


if __name__ == "__main__":
    sys.exit(main())
