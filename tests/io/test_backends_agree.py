#!/usr/bin/env python3
"""Both builds of libisomend_io read every stack the same (ctest io_backends_agree).

The OpenImageIO build (the command line's) and the portable build on libtiff,
OpenEXR and libpng (the Blender add-on's) are loaded in turn, each in a
process of its own (they share a SONAME), through the ctypes wrapper
(ISOMEND_LIB_DIR).  Each process opens every stack of tests/io's manifests
and the real MRI of scripts/get-test-data.sh and records what it delivers:
dimensions, type, spacing and its sources, kind, format, the volume's bytes
(SHA-256) and the mesh at the suggested iso with DMC and padding (SHA-256 of
positions, normals and triangles); or, for a bad stack, the status and the
message.  The two records must be equal case by case, byte for byte, except:
  - where a build's image library differs on purpose (DIFFERENT below);
  - error messages, whose wording is the library's: both must have the same
    status and name the file the manifest names.

Usage: test_backends_agree.py --wrapper DIR --core DIR --oiio DIR --portable DIR
                              --stacks DIR [--get-test-data SCRIPT]
"""
import argparse
import hashlib
import json
import os
import subprocess
import sys

# name -> (the build that refuses it, why the builds differ there); checked: that build
# refuses, the other reads
DIFFERENT = {
    "bilevel": ("oiio", "1-bit TIFF without a BitsPerSample tag: OpenImageIO 2.4 misreads it "
                        "(refused), libtiff reads it"),
    "jpeg_folder": ("portable", "JPEG: read by OpenImageIO, refused by name by the portable build"),
}


def manifest_cases(stacks):
    """{name: (kind 'ok'/'err', expected substring or None, sources, channel, first, count, step)}
    from both manifests."""
    cases = {}
    for manifest in ("manifest.tsv", "manifest_portable.tsv"):
        for line in open(os.path.join(stacks, manifest)):
            f = line.rstrip("\n").split("\t")
            if f[0] == "ok":
                entry = ("ok", None, f[16:], int(f[8]), int(f[9]), int(f[10]), int(f[11]))
            else:
                entry = ("err", f[3], f[8:], int(f[4]), int(f[5]), int(f[6]), int(f[7]))
            cases.setdefault(f[1], entry)
    return cases


def sha(*arrays):
    h = hashlib.sha256()
    for a in arrays:
        if a is not None:
            h.update(a.tobytes())
    return h.hexdigest()


def dump(args):
    """Runs in the child: one build's record of every case, as JSON on stdout."""
    sys.path.insert(0, args.wrapper)
    import numpy as np
    import isomend
    record = {"_libraries": isomend.io_image_libraries()}
    cases = manifest_cases(args.stacks)
    if args.real:
        cases["mri_t1_small"] = ("ok", None, [args.real], -1, 0, 0, 1)
    for name, (_, _, sources, channel, first, count, step) in sorted(cases.items()):
        paths = [s if os.path.isabs(s) else os.path.join(args.stacks, s) for s in sources]
        kwargs = dict(channel=channel, first=first, count=count, step=step)
        try:
            with isomend.open_source(paths if len(paths) > 1 else paths[0], **kwargs) as src:
                # loads the volume (refused first if it is too large), then extracts
                mesh = src.extract(iso=None, method="dmc", pad=True)
                vol = src.read()
                out = {"dims": src.dims, "dtype": np.dtype(src.dtype).name, "spacing": src.spacing,
                       "spacing_sources": src.spacing_sources, "kind": src.kind,
                       "format": src.format, "volume": sha(vol),
                       "mesh": [mesh.iso, mesh.vertex_count, mesh.triangle_count,
                                sha(mesh.positions, mesh.normals, mesh.triangles)]}
        except isomend.IsomendError as exc:
            out = {"status": exc.status_name, "message": str(exc)}
        record[name] = out
    json.dump(record, sys.stdout)


def main():
    ap = argparse.ArgumentParser()
    for opt in ("--wrapper", "--core", "--oiio", "--portable", "--stacks"):
        ap.add_argument(opt, required=True)
    ap.add_argument("--get-test-data")
    ap.add_argument("--dump", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--real", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.dump:
        dump(args)
        return

    real = None
    if args.get_test_data:
        r = subprocess.run(["bash", args.get_test_data, "mri_t1_small"], capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit("FAIL: scripts/get-test-data.sh could not provide the real volume: " + r.stderr)
        root = os.environ.get("ISOMEND_TESTDATA") or os.path.join(
            os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "isomend")
        real = os.path.join(root, "mri_t1_small", "tiff")

    records = {}
    for build, lib_dir in (("oiio", args.oiio), ("portable", args.portable)):
        env = dict(os.environ, ISOMEND_LIB_DIR=os.pathsep.join([args.core, lib_dir]))
        cmd = [sys.executable, os.path.abspath(__file__), "--dump", "--wrapper", args.wrapper,
               "--core", args.core, "--oiio", args.oiio, "--portable", args.portable,
               "--stacks", args.stacks] + (["--real", real] if real else [])
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=500)
        if r.returncode != 0:
            sys.exit("FAIL: the %s build's run failed: %s" % (build, r.stderr[-3000:]))
        records[build] = json.loads(r.stdout)
        print("%-8s %s" % (build, records[build]["_libraries"]))
    a, b = records["oiio"], records["portable"]
    assert a["_libraries"].startswith("OpenImageIO"), a["_libraries"]
    assert b["_libraries"].startswith("libtiff"), b["_libraries"]
    cases = manifest_cases(args.stacks)
    failures = []
    same_volumes = same_errors = 0
    for name in sorted(set(a) - {"_libraries"}):
        x, y = a[name], b.get(name)
        if name in DIFFERENT:
            refuser, why = DIFFERENT[name]
            refused, read = (x, y) if refuser == "oiio" else (y, x)
            if not ("status" in refused and "status" not in read):
                failures.append("%s: expected %s; got %s / %s" % (name, why, x, y))
            else:
                print("diff %-22s %s" % (name, why))
            continue
        if "status" in x or "status" in y:
            want = cases[name][1] if name in cases else None
            if "status" not in x or "status" not in y or x["status"] != y["status"]:
                failures.append("%s: OpenImageIO %s, portable %s" % (name, x, y))
            elif want and not (want.split(":")[0] in x["message"] and want.split(":")[0] in y["message"]):
                failures.append("%s: a message does not name %r: %r / %r"
                                % (name, want, x["message"], y["message"]))
            else:
                same_errors += 1
                print("err  %-22s %s | %s" % (name, x["status"], y["message"]))
            continue
        if x != y:
            diff = {k: (x.get(k), y.get(k)) for k in set(x) | set(y) if x.get(k) != y.get(k)}
            failures.append("%s: %s" % (name, diff))
        else:
            same_volumes += 1
            print("ok   %-22s %-7s %-7s %-10s mesh at %g: %d triangles"
                  % (name, x["format"], x["dtype"], "x".join(map(str, x["dims"])), x["mesh"][0],
                     x["mesh"][2]))
    if real and "mri_t1_small" not in a:
        failures.append("the real MRI was not read")
    print("%d stacks read identically, %d refused alike, %d differences%s"
          % (same_volumes, same_errors, len(failures), "" if not failures else ":"))
    for f in failures:
        print("FAIL: " + f)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
