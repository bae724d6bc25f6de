#!/usr/bin/env python3
"""The add-on package the Debian 13 (trixie) build made, in this machine's
Blender (ctest blender_trixie_package, label after_trixie: scripts/test-trixie.sh
runs it with ISOMEND_TRIXIE_BUILD set to the trixie build tree).

What "the reverse" can mean: a shared library built against glibc 2.41
references the symbol versions of the glibc it was linked with, and an older
glibc's dynamic linker refuses a library that needs a version it does not
have.  So the package from the newer system loads here only if the highest
GLIBC_ version its libraries reference (lib/build-info.json, checked against
the libraries themselves) is at most this system's glibc.  This test states
which case holds and proves the add-on behaves accordingly:
  - the libraries' glibc is old enough: the full import test
    (run_blender_tests.py) passes with that package;
  - it is too new: the add-on installs and enables, and the import refuses
    with the message naming both versions (blender_refuse_test.py), no
    traceback.

Usage: run_other_build.py --blender EXE --cli isomend --work DIR --runner run_blender_tests.py
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from check_bundle import elf_dynamic, vkey  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    for opt in ("--blender", "--cli", "--work", "--runner"):
        ap.add_argument(opt, required=True)
    args = ap.parse_args()
    other = os.environ.get("ISOMEND_TRIXIE_BUILD")
    if not other or not os.path.isdir(other):
        sys.exit("FAIL: ISOMEND_TRIXIE_BUILD is not set or missing (scripts/test-trixie.sh sets it)")
    package = os.path.join(other, "blender_addon", "isomend_import.zip")
    if not os.path.exists(package):
        sys.exit("FAIL: %s not found: the trixie build made no add-on" % package)
    work = os.path.abspath(args.work)
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    unpacked = os.path.join(work, "package")
    with zipfile.ZipFile(package) as zf:
        zf.extractall(unpacked)
    lib = os.path.join(unpacked, "isomend_import", "lib")
    # what the libraries themselves reference, and what build-info says
    refs = set()
    for name in os.listdir(lib):
        if ".so" in name:
            for names in elf_dynamic(os.path.join(lib, name))[3].values():
                refs |= {v[6:] for v in names if v.startswith("GLIBC_")}
    need = max(refs, key=vkey)
    info_path = os.path.join(lib, "build-info.json")
    info = json.load(open(info_path)) if os.path.exists(info_path) else None
    have = os.confstr("CS_GNU_LIBC_VERSION").split()[1]
    print("trixie package %s: its libraries reference GLIBC_%s at most (build-info: %s); this "
          "system has glibc %s" % (package, need, info and info.get("glibc"), have))
    if info is None:
        expect, loads = "cannot be loaded", False   # not portable: the trixie system's libraries
    elif info.get("glibc") != need:
        sys.exit("FAIL: build-info.json says glibc %s, the libraries need %s" % (info.get("glibc"), need))
    else:
        loads = vkey(need) <= vkey(have)
        expect = "need glibc %s or newer and this system has glibc %s" % (need, have)
    if loads:
        print("-> it can load here: the full import test with it")
        r = subprocess.run([sys.executable, args.runner, "--blender", args.blender, "--package", package,
                            "--install", "legacy", "--cli", args.cli, "--work", os.path.join(work, "import")])
        sys.exit(r.returncode)
    print("-> it cannot load here: the add-on must refuse with %r" % expect)
    stack = os.path.join(work, "stack")
    os.makedirs(stack)
    import numpy as np
    import tifffile
    for k in range(3):
        tifffile.imwrite(os.path.join(stack, "s_%d.tif" % k), np.full((8, 8), 10 * k, np.uint8))
    spec = os.path.join(work, "refuse.json")
    json.dump({"package": package, "install": "legacy", "directory": stack, "expect": expect}, open(spec, "w"))
    home = os.path.join(work, "home")
    env = dict(os.environ, BLENDER_USER_SCRIPTS=os.path.join(home, "scripts"),
               BLENDER_USER_CONFIG=os.path.join(home, "config"), HOME=home,
               XDG_CACHE_HOME=os.path.join(home, "cache"))
    env.pop("ISOMEND_LIB_DIR", None)
    r = subprocess.run([args.blender, "-b", "--factory-startup", "-noaudio", "--python-exit-code", "1",
                        "--python", os.path.join(HERE, "blender_refuse_test.py"), "--", spec],
                       capture_output=True, text=True, env=env, timeout=300)
    out = r.stdout + r.stderr
    print(out)
    if r.returncode != 0 or "refuse test: passed" not in out or "Traceback" in out:
        sys.exit("FAIL: the trixie package did not refuse cleanly")


if __name__ == "__main__":
    main()
