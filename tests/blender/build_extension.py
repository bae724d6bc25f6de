#!/usr/bin/env python3
"""Blender's own tool builds the extension from the staged add-on folder
(ctest blender_extension_build, Blender 4.2+):

    blender --command extension build --source-dir STAGE --output-dir WORK --split-platforms
    blender --command extension validate WORK/isomend_import-VERSION-linux_x64.zip

and the package it builds holds the same files, byte for byte, as the one
the CMake build packages (blender_addon/CMakeLists.txt, which also runs where
Blender is older than 4.2).

Usage: build_extension.py --blender EXE --stage DIR --package ZIP --work DIR
"""
import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import zipfile


def contents(path):
    with zipfile.ZipFile(path) as zf:
        return {i.filename: hashlib.sha256(zf.read(i)).hexdigest() for i in zf.infolist() if not i.is_dir()}


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
    ours, theirs = contents(args.package), contents(out)
    if ours != theirs:
        diff = sorted(set(ours.items()) ^ set(theirs.items()))
        sys.exit("FAIL: Blender's package differs from the CMake-built one: %s" % diff)
    print("ok: Blender's `extension build` makes the same %d files as the build (%s)"
          % (len(ours), ", ".join(sorted(ours))))


if __name__ == "__main__":
    main()
