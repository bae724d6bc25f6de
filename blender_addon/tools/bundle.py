#!/usr/bin/env python3
"""Makes the add-on's lib/ folder loadable on any x86-64 Linux whose C library
is at least as new as the build machine's (what auditwheel does for wheels).

    bundle.py --lib-dir STAGE/lib LIB [LIB ...]

Each LIB (the add-on's own libraries: libisomend, libisomend_io) is copied
into lib/ under its SONAME, then every shared library they need, directly or
through each other, is copied there too under its SONAME, except the ones
every Linux has (SYSTEM_LIBRARIES: glibc's own libraries, libstdc++, libgcc_s).
Every copy gets RUNPATH $ORIGIN (patchelf), so the dynamic linker looks
for a bundled library's dependencies next to it first, and loses its debug
information.  lib/build-info.json records what was bundled and the highest
GLIBC_, GLIBCXX_ and CXXABI_ symbol versions any copy references: the oldest
C and C++ runtimes the package loads on.  The add-on reads it before it
loads anything (import_stack.library_problem) and refuses with a message
naming both versions rather than failing with a traceback.

Tools: ldd (where the build machine resolves each SONAME), objdump -p
(NEEDED entries, SONAME, symbol version references), patchelf, strip.
"""
import argparse
import json
import os
import platform
import re
import shutil
import subprocess
import sys

# Libraries that every x86-64 Linux with glibc has, in versions that only grow:
# never bundled (the same list as auditwheel's manylinux policies, less the X11
# and GLib libraries nothing here needs).  A bundled copy of glibc's own
# libraries would not work anyway: they must match the system's ld.so.
SYSTEM_LIBRARIES = frozenset([
    "libc.so.6", "libm.so.6", "libpthread.so.0", "libdl.so.2", "librt.so.1", "libutil.so.1",
    "libresolv.so.2", "libnsl.so.1", "libanl.so.1", "ld-linux-x86-64.so.2",
    "libstdc++.so.6", "libgcc_s.so.1",
])

VERSIONED = ("GLIBC", "GLIBCXX", "CXXABI", "GCC")


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit("bundle: %s failed: %s" % (" ".join(cmd), r.stderr.strip() or r.stdout.strip()))
    return r.stdout


def dynamic_info(path):
    """(soname, [needed], runpath, {prefix: set of versions referenced}) from objdump -p."""
    out = run(["objdump", "-p", path])
    soname, needed, runpath = None, [], None
    versions = {p: set() for p in VERSIONED}
    for line in out.splitlines():
        words = line.split()
        if len(words) >= 2 and words[0] == "NEEDED":
            needed.append(words[1])
        elif len(words) >= 2 and words[0] == "SONAME":
            soname = words[1]
        elif len(words) >= 2 and words[0] in ("RUNPATH", "RPATH"):
            runpath = words[1]
        else:
            m = re.search(r"\b(GLIBC|GLIBCXX|CXXABI|GCC)_(\d+(?:\.\d+)*)\b", line)
            if m and ("0x" in line):  # "    0x0d696914 0x00 05 GLIBC_2.14" (Version References)
                versions[m.group(1)].add(m.group(2))
    return soname, needed, runpath, versions


def resolved_by_ldd(path):
    """{soname: path} of everything the build machine's loader finds for `path`."""
    env = {k: v for k, v in os.environ.items() if k != "LD_LIBRARY_PATH"}
    r = subprocess.run(["ldd", path], capture_output=True, text=True, env=env)
    if r.returncode != 0:
        sys.exit("bundle: ldd %s failed: %s" % (path, r.stderr.strip()))
    found = {}
    for line in r.stdout.splitlines():
        m = re.match(r"\s*(\S+) => (\S+) \(0x", line)
        if m:
            found[m.group(1)] = m.group(2)
        elif "=> not found" in line:
            sys.exit("bundle: %s needs %s, which this machine does not have"
                     % (path, line.split()[0]))
    return found


def vkey(v):
    return tuple(int(x) for x in v.split("."))


def highest(versions):
    return max(versions, key=vkey) if versions else None


def debian_package(path):
    """'libtiff6 4.5.0-6+deb12u4' for a file dpkg knows, else None."""
    real = os.path.realpath(path)
    for candidate in (path, real, real.replace("/usr/lib/", "/lib/"), real.replace("/lib/", "/usr/lib/", 1)):
        r = subprocess.run(["dpkg-query", "-S", candidate], capture_output=True, text=True)
        if r.returncode == 0 and ":" in r.stdout:
            pkg = r.stdout.split(":", 1)[0].split(",")[0].strip()
            pkg_name = pkg.split(":")[0]
            v = subprocess.run(["dpkg-query", "-W", "-f", "${Version}", pkg], capture_output=True,
                               text=True)
            return "%s %s" % (pkg_name, v.stdout.strip()) if v.returncode == 0 else pkg_name
    return None


def system_glibc():
    name = os.confstr("CS_GNU_LIBC_VERSION") or ""
    return name.split()[1] if name.startswith("glibc ") else None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lib-dir", required=True, help="the add-on's lib/ folder (emptied first)")
    ap.add_argument("--strip", default="strip", help="the strip program")
    ap.add_argument("--patchelf", default="patchelf", help="the patchelf program")
    ap.add_argument("libs", nargs="+", help="the add-on's own shared libraries")
    args = ap.parse_args()

    for tool in (args.patchelf, args.strip, "objdump", "ldd"):
        if not shutil.which(tool):
            sys.exit("bundle: %s not found (apt-get install patchelf binutils)" % tool)
    out = os.path.abspath(args.lib_dir)
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)

    # The add-on's own libraries first: their SONAMEs are bundled by definition.
    sources = {}   # soname -> path on the build machine
    own = []
    for lib in args.libs:
        soname = dynamic_info(lib)[0] or os.path.basename(lib)
        sources[soname] = os.path.realpath(lib)
        own.append(soname)
    # Everything they pull in, as the build machine resolves it.
    for lib in args.libs:
        for soname, path in resolved_by_ldd(lib).items():
            if soname in sources or soname in SYSTEM_LIBRARIES or soname.startswith("linux-vdso"):
                continue
            sources[soname] = os.path.realpath(path)

    for soname, path in sorted(sources.items()):
        dst = os.path.join(out, soname)
        shutil.copyfile(path, dst)
        os.chmod(dst, 0o755)
        run([args.strip, "--strip-debug", dst])
        run([args.patchelf, "--set-rpath", "$ORIGIN", dst])

    # What the copies need, checked again on the copies themselves.
    record = {"built_on": platform.platform(), "system_glibc": system_glibc(), "libraries": []}
    wanted = {p: set() for p in VERSIONED}
    for soname in sorted(sources):
        dst = os.path.join(out, soname)
        got_soname, needed, runpath, versions = dynamic_info(dst)
        missing = [n for n in needed if n not in sources and n not in SYSTEM_LIBRARIES]
        if missing:
            sys.exit("bundle: %s needs %s, neither bundled nor a system library" % (soname, missing))
        if runpath != "$ORIGIN":
            sys.exit("bundle: %s has RUNPATH %r after patchelf" % (soname, runpath))
        for p in VERSIONED:
            wanted[p] |= versions[p]
        record["libraries"].append({
            "soname": soname, "own": soname in own, "from": sources[soname],
            "package": None if soname in own else debian_package(sources[soname]),
            "bytes": os.path.getsize(dst), "needed": needed,
            "glibc": highest(versions["GLIBC"])})
    record["glibc"] = highest(wanted["GLIBC"])
    record["glibcxx"] = highest(wanted["GLIBCXX"])
    record["cxxabi"] = highest(wanted["CXXABI"])
    record["gcc"] = highest(wanted["GCC"])
    record["system_libraries"] = sorted(SYSTEM_LIBRARIES)
    record["bytes"] = sum(x["bytes"] for x in record["libraries"])
    if record["system_glibc"] and record["glibc"] and vkey(record["glibc"]) > vkey(record["system_glibc"]):
        sys.exit("bundle: the libraries reference GLIBC_%s, newer than this machine's %s"
                 % (record["glibc"], record["system_glibc"]))
    tmp = os.path.join(out, "build-info.json.tmp")
    with open(tmp, "w") as fp:
        json.dump(record, fp, indent=1)
        fp.write("\n")
    os.replace(tmp, os.path.join(out, "build-info.json"))
    print("bundle: %d libraries, %.1f MB, glibc >= %s, GLIBCXX >= %s"
          % (len(record["libraries"]), record["bytes"] / 1e6, record["glibc"], record["glibcxx"]))


if __name__ == "__main__":
    main()
