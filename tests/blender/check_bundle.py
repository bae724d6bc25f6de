#!/usr/bin/env python3
"""The portable add-on's lib/ is self-contained (ctest blender_bundle_check).

Reads every shared library in LIB_DIR with an ELF reader of its own (not the
build's objdump) and checks, auditwheel's way:
  1. every NEEDED soname is bundled, or one of the libraries every Linux has
     (glibc's, libstdc++, libgcc_s);
  2. every library's RUNPATH is $ORIGIN, so the bundled copies are found first;
  3. the highest GLIBC_ symbol version referenced is at most this machine's
     glibc (the package loads on any glibc as new as the build's), and it is
     the one lib/build-info.json records (what the add-on checks before it
     loads anything); build-info lists exactly the files bundled;
  4. in a plain Python process (no host that has loaded libraries of its
     own), loading the add-on's importer takes every bundled library from
     LIB_DIR and no copy from the system (/proc/self/maps: the files mapped).

Usage: check_bundle.py LIB_DIR
"""
import json
import os
import struct
import subprocess
import sys

SYSTEM = {"libc.so.6", "libm.so.6", "libpthread.so.0", "libdl.so.2", "librt.so.1", "libutil.so.1",
          "libresolv.so.2", "libnsl.so.1", "libanl.so.1", "ld-linux-x86-64.so.2",
          "libstdc++.so.6", "libgcc_s.so.1"}

DT_NEEDED, DT_STRTAB, DT_SONAME, DT_RPATH, DT_RUNPATH, DT_VERNEED, DT_VERNEEDNUM = 1, 5, 14, 15, 29, \
    0x6ffffffe, 0x6fffffff


def elf_dynamic(path):
    """(soname, needed, runpath, {library: set of version names}) of an ELF64 LE shared object."""
    data = open(path, "rb").read()
    if data[:4] != b"\x7fELF" or data[4] != 2 or data[5] != 1:
        raise ValueError("%s: not a 64-bit little-endian ELF file" % path)
    phoff, = struct.unpack_from("<Q", data, 0x20)
    phentsize, phnum = struct.unpack_from("<HH", data, 0x36)
    loads, dynamic = [], None
    for i in range(phnum):
        p_type, _, p_offset, p_vaddr, _, p_filesz, _, _ = struct.unpack_from("<IIQQQQQQ", data, phoff + i * phentsize)
        if p_type == 1:
            loads.append((p_vaddr, p_offset, p_filesz))
        elif p_type == 2:
            dynamic = (p_offset, p_filesz)

    def offset(vaddr):
        for va, off, size in loads:
            if va <= vaddr < va + size:
                return off + vaddr - va
        raise ValueError("%s: address %#x outside the file" % (path, vaddr))

    entries = []
    for k in range(dynamic[1] // 16):
        tag, val = struct.unpack_from("<qQ", data, dynamic[0] + 16 * k)
        if tag == 0:
            break
        entries.append((tag, val))
    strtab = offset(dict(entries)[DT_STRTAB])

    def string(o):
        end = data.index(b"\0", strtab + o)
        return data[strtab + o:end].decode()

    tags = dict(entries)
    needed = [string(v) for t, v in entries if t == DT_NEEDED]
    soname = string(tags[DT_SONAME]) if DT_SONAME in tags else None
    runpath = string(tags[DT_RUNPATH]) if DT_RUNPATH in tags else None
    rpath = string(tags[DT_RPATH]) if DT_RPATH in tags else None
    versions = {}
    if DT_VERNEED in tags:
        at = offset(tags[DT_VERNEED])
        for _ in range(tags[DT_VERNEEDNUM]):
            _, cnt, file_, aux, nxt = struct.unpack_from("<HHIII", data, at)
            names = versions.setdefault(string(file_), set())
            a = at + aux
            for _ in range(cnt):
                _, _, _, name, anext = struct.unpack_from("<IHHII", data, a)
                names.add(string(name))
                a += anext
            at += nxt
    return soname, needed, runpath or rpath, versions


def vkey(v):
    return tuple(int(x) for x in v.split("."))


def main():
    lib_dir = os.path.abspath(sys.argv[1])
    failures = []
    libs = sorted(f for f in os.listdir(lib_dir) if ".so" in f)
    info = json.load(open(os.path.join(lib_dir, "build-info.json")))
    glibc_refs = set()
    for name in libs:
        soname, needed, runpath, versions = elf_dynamic(os.path.join(lib_dir, name))
        if soname != name:
            failures.append("%s: its SONAME is %s (the file must carry the SONAME)" % (name, soname))
        for n in needed:
            if n not in libs and n not in SYSTEM:
                failures.append("%s needs %s: neither bundled nor a system library" % (name, n))
        if runpath != "$ORIGIN":
            failures.append("%s: RUNPATH %r, not $ORIGIN" % (name, runpath))
        for lib, names in versions.items():
            glibc_refs |= {v[6:] for v in names if v.startswith("GLIBC_")}
            if lib not in SYSTEM and lib not in libs:
                failures.append("%s: versions required from %s, which is not bundled" % (name, lib))
    have = os.confstr("CS_GNU_LIBC_VERSION").split()[1]
    top = max(glibc_refs, key=vkey)
    if vkey(top) > vkey(have):
        failures.append("the libraries reference GLIBC_%s, newer than this machine's %s" % (top, have))
    if info["glibc"] != top:
        failures.append("build-info.json records glibc %s, the libraries need %s" % (info["glibc"], top))
    listed = sorted(x["soname"] for x in info["libraries"])
    if listed != libs:
        failures.append("build-info.json lists %s, lib/ holds %s" % (listed, libs))

    # 4. where a plain process finds each library: the files it maps when it
    # loads the importer, by SONAME (a file name may be libz.so.1.2.13).  A
    # library the process had loaded before (Python itself links zlib) is the
    # process's own, shared by SONAME: allowed, and reported.
    code = ("import ctypes, sys; d = sys.argv[1]\n"
            "def maps(): return sorted({l.split()[-1] for l in open('/proc/self/maps') if '.so' in l})\n"
            "before = maps()\n"
            "ctypes.CDLL(d + '/libisomend.so.0', mode=ctypes.RTLD_GLOBAL)\n"
            "ctypes.CDLL(d + '/libisomend_io.so.0')\n"
            "print(' '.join(before)); print(' '.join(p for p in maps() if p not in before))\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith("LD_")}
    r = subprocess.run([sys.executable, "-c", code, lib_dir], capture_output=True, text=True, env=env)
    if r.returncode != 0:
        failures.append("loading the importer failed: %s" % r.stderr[-2000:])
    lines = (r.stdout.splitlines() + ["", ""])[:2]
    before, after = lines[0].split(), lines[1].split()

    def by_soname(paths):
        out = {}
        for path in paths:
            try:
                out.setdefault(elf_dynamic(path)[0] or os.path.basename(path), []).append(path)
            except (ValueError, KeyError, OSError, struct.error):
                pass
        return out
    had, new_maps = by_soname(before), by_soname(after)
    shared = []
    for name in libs:
        if name in had:
            shared.append(name)
            continue
        paths = new_maps.get(name, [])
        if not paths:
            failures.append("%s was not loaded with the importer" % name)
        for path in paths:
            if os.path.dirname(os.path.realpath(path)) != os.path.realpath(lib_dir):
                failures.append("%s was loaded from %s, not from the package" % (name, path))
    for soname, paths in new_maps.items():
        if soname not in libs and soname not in SYSTEM:
            failures.append("%s was loaded from %s: not bundled, not a system library" % (soname, paths))
    print("loaded from the package: %d; already in the process (shared by SONAME): %s"
          % (len(libs) - len(shared), ", ".join(shared) or "none"))

    print("%d libraries in %s, %.1f MB; highest GLIBC_ referenced %s (this machine %s); GLIBCXX %s"
          % (len(libs), lib_dir, sum(os.path.getsize(os.path.join(lib_dir, n)) for n in libs) / 1e6,
             top, have, info.get("glibcxx")))
    for x in info["libraries"]:
        print("  %-28s %9d  %s" % (x["soname"], x["bytes"], x["package"] or "(isomend)"))
    for f in failures:
        print("FAIL: " + f)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
