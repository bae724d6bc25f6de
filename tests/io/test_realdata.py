#!/usr/bin/env python3
"""A real volume from a Debian package through the importer and the command line.

Usage: test_realdata.py GET_TEST_DATA_SH IO_REALDATA [ISOMEND_CLI|-]

Runs scripts/get-test-data.sh mri_t1_small (apt-get download of
insighttoolkit5-examples, cached in $ISOMEND_TESTDATA or ~/.cache/isomend),
then io_realdata (the C API) and, if given, `isomend info/extract` on the TIFF
folder: no hole edges at the suggested iso, none at all with --pad, and the
same mesh from the TIFF stack as from the raw file.  A failed download FAILS
the test (it never passes silently without data).
"""
import json
import os
import subprocess
import sys
import tempfile


def run(cmd, **kw):
    print("$", " ".join(cmd), flush=True)
    return subprocess.run(cmd, capture_output=True, text=True, **kw)


def main():
    script, prog = sys.argv[1], sys.argv[2]
    cli = sys.argv[3] if len(sys.argv) > 3 and sys.argv[3] != "-" else None
    r = run(["bash", script, "mri_t1_small"])
    sys.stderr.write(r.stderr)
    if r.returncode != 0:
        sys.exit("FAIL: scripts/get-test-data.sh could not provide the real volume "
                 "(exit %d); see its message above" % r.returncode)
    root = os.environ.get("ISOMEND_TESTDATA") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "isomend")
    d = os.path.join(root, "mri_t1_small")
    meta = json.load(open(os.path.join(d, "mri_t1_small.json")))
    tname = {"uint8": "u8", "int16": "i16", "uint16": "u16", "float32": "f32"}[meta["dtype"]]
    nx, ny, nz = meta["dims_xyz"]
    sx, sy, sz = meta["spacing_xyz_mm"]
    tiff = os.path.join(d, "tiff")
    raw = os.path.join(d, meta["raw"])
    r = run([prog, tiff, raw, tname, str(nx), str(ny), str(nz), repr(sx), repr(sy), repr(sz)])
    print(r.stdout + r.stderr)
    if r.returncode != 0:
        sys.exit("FAIL: io_realdata")
    if not cli:
        print("ok (the command line was not built: only the C API was tested)")
        return
    with tempfile.TemporaryDirectory() as tmp:
        r = run([cli, "info", tiff, "--json", "-"])
        assert r.returncode == 0, r.stderr
        info = json.loads(r.stdout)
        assert info["dims"] == [nx, ny, nz] and info["type"] == tname, info
        assert info["spacing_from"] == ["imagej"] * 3, info
        iso = info["suggested_iso"]
        results = {}
        for name, src, extra in (("tiff", [tiff], []), ("tiff_pad", [tiff], ["--pad"]),
                                 ("raw_pad", [raw, "--raw", "%d,%d,%d:%s" % (nx, ny, nz, tname),
                                              "--spacing", "%r,%r,%r" % (sx, sy, sz), "--iso", repr(iso)],
                                  ["--pad"])):
            out = os.path.join(tmp, name + ".ply")
            r = run([cli, "extract"] + src + ["-o", out, "--json", "-", "--quiet"] + extra)
            assert r.returncode == 0, r.stderr
            j = json.loads(r.stdout)
            results[name] = (j, open(out, "rb").read())
            c = j["check"]
            print("%-9s iso %g: %d vertices, %d triangles, %d hole edges, %d border edges, read %.1f ms"
                  % (name, j["iso"], j["vertices"], j["triangles"], c["holes"], c["border_edges"],
                     j["timings_ms"]["read"]))
            assert c["holes"] == 0 and c["nonmanifold_edges"] == 0 and c["misoriented_edges"] == 0, c
        assert results["tiff"][0]["iso_suggested"] and results["tiff"][0]["iso"] == iso
        assert results["tiff_pad"][0]["check"]["border_edges"] == 0
        a, b = results["tiff_pad"][1], results["raw_pad"][1]
        body = lambda x: x[x.index(b"end_header\n"):]
        assert body(a) == body(b), "the TIFF stack's mesh differs from the raw volume's"
    print("ok")


if __name__ == "__main__":
    main()
