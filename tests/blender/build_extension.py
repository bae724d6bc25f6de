#!/usr/bin/env python3
"""Blender's own tool builds the extension from the staged add-on folder
(ctest blender_extension_build, Blender 4.2+):

    blender --command extension build --source-dir STAGE --output-dir WORK --split-platforms
    blender --command extension validate WORK/isomend_import-VERSION-linux_x64.zip

and the package it builds holds the same files, byte for byte, as the one
the CMake build packages (blender_addon/CMakeLists.txt, which also runs where
Blender is older than 4.2), except the block Blender appends to the manifest
("# BEGIN GENERATED CONTENT" ... [build.generated] platforms, wheels), which
must name linux-x64 and no wheels.

Usage: build_extension.py --blender EXE --stage DIR --package ZIP --work DIR
"""
import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import zipfile


GENERATED = "\n\n# BEGIN GENERATED CONTENT."


def contents(path):
    """{name: sha256}; the manifest without Blender's generated block, which is returned too."""
    out, generated = {}, None
    with zipfile.ZipFile(path) as zf:
        for i in zf.infolist():
            if i.is_dir():
                continue
            data = zf.read(i)
            if i.filename == "blender_manifest.toml" and GENERATED.encode() in data:
                data, generated = data.split(GENERATED.encode(), 1)
                generated = generated.decode()
            out[i.filename] = hashlib.sha256(data).hexdigest()
    return out, generated


def main():
    ap = argparse.ArgumentParser()
    for opt in ("--blender", "--stage", "--package", "--work"):
        ap.add_argument(opt, required=True)
    args = ap.parse_args()
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    env = dict(os.environ, HOME=args.work)
    base = [args.blender, "-b", "--factory-startup", "--command", "extension"]
    r = subprocess.run(base + ["build", "--source-dir", args.stage, "--output-dir", args.work,
                               "--split-platforms"], capture_output=True, text=True, env=env, timeout=120)
    print(r.stdout + r.stderr)
    built = [f for f in os.listdir(args.work) if f.endswith(".zip")]
    if r.returncode != 0 or built != [os.path.basename(args.package)]:
        sys.exit("FAIL: extension build exit %d, made %s, expected %s"
                 % (r.returncode, built, os.path.basename(args.package)))
    out = os.path.join(args.work, built[0])
    r = subprocess.run(base + ["validate", out], capture_output=True, text=True, env=env, timeout=120)
    print(r.stdout + r.stderr)
    if r.returncode != 0 or "rror" in r.stdout + r.stderr:
        sys.exit("FAIL: extension validate of Blender's own build")
    (ours, _), (theirs, generated) = contents(args.package), contents(out)
    if generated is None or 'platforms = ["linux-x64"]' not in generated or "wheels = []" not in generated:
        sys.exit("FAIL: Blender's manifest has no generated block for linux-x64: %r" % generated)
    if ours != theirs:
        diff = sorted(set(ours.items()) ^ set(theirs.items()))
        sys.exit("FAIL: Blender's package differs from the CMake-built one: %s" % diff)
    print("ok: Blender's `extension build` makes the same %d files as the build (%s)"
          % (len(ours), ", ".join(sorted(ours))))


if __name__ == "__main__":
    main()
