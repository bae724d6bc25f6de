#!/usr/bin/env python3
"""The `isomend` command line: every documented flag and every error path.

Each error case checks the exit code (2 usage, 1 failure), that the message
names the file or flag and says what is wrong, and that neither the output
nor a temporary file is left behind.  Success cases check results, not just
"it ran": mesh contents against an independent reading of the files, JSON
against the thesis's F1/F2 facts, flags against their documented effect.

Runs only isomend's C code (Python drives it), so the sanitizer build runs
it too.  Standard library only (+ a pseudo-terminal for the progress bar).

usage: test_cli.py --isomend PATH --samples DIR --work DIR
"""
import argparse
import gzip
import json
import os
import pty
import shutil
import struct
import subprocess
import sys

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
import clitest  # noqa: E402
from clitest import fail, read_ply_header  # noqa: E402


class Runner:
    def __init__(self, exe, work):
        self.exe = exe
        self.work = work

    def run(self, *args, stdin=None):
        p = subprocess.run([self.exe, *args], cwd=self.work, capture_output=True,
                           text=True, timeout=120, stdin=subprocess.DEVNULL)
        return p.returncode, p.stdout, p.stderr

    def path(self, name):
        return os.path.join(self.work, name)


def leftovers(work):
    """Temporary files left anywhere under the work folder."""
    found = []
    for root, _dirs, files in os.walk(work):
        found += [os.path.join(root, f) for f in files if ".tmp" in f]
    return found


def expect_error(r, name, args, code, substrings, outputs=()):
    rc, out, err = r.run(*args)
    if rc != code:
        fail(name, f"exit {rc}, expected {code}; stderr: {err.strip()}")
    lines = [l for l in err.splitlines() if l.strip()]
    if len(lines) != 1:
        fail(name, f"expected one error line, got {len(lines)}: {err!r}")
    elif not lines[0].startswith("isomend: "):
        fail(name, f"message does not start with 'isomend: ': {lines[0]!r}")
    for s in substrings:
        if s not in err:
            fail(name, f"message {err.strip()!r} lacks {s!r}")
    for o in outputs:
        if os.path.exists(r.path(o)):
            fail(name, f"output {o} left behind")
    tmp = leftovers(r.work)
    if tmp:
        fail(name, f"temporary files left: {tmp}")
    for t in tmp:
        os.unlink(t)


def expect_ok(r, name, args):
    rc, out, err = r.run(*args)
    if rc != 0:
        fail(name, f"exit {rc}; stderr: {err.strip()}")
    return out, err


# ------------------------------------------------------------------ file readers

def read_ply(path):
    """Binary little-endian PLY as written by isomend -> (props, verts, faces)."""
    data = open(path, "rb").read()
    end, nv, nf, props = read_ply_header(data)
    stride = 4 * len(props)
    verts = [struct.unpack_from("<" + "f" * len(props), data, end + i * stride) for i in range(nv)]
    off = end + nv * stride
    faces = []
    for _ in range(nf):
        n = data[off]
        faces.append(struct.unpack_from("<%dI" % n, data, off + 1))
        off += 1 + 4 * n
    assert off == len(data), "trailing bytes in PLY"
    return props, verts, faces


def f1(x, y, z):
    return 4 * y + 4 * (x - z) ** 2 - 5


def f2(x, y, z):
    return 4 * (y - 1) ** 2 + 2 * (x - z) ** 2 - 2 * (x + z - 3) ** 2 + 1


def grid(fn):
    return [float(fn(x, y, z)) for z in range(4) for y in range(4) for x in range(4)]


def write_nrrd(path, type_name, fmt, dims, values, encoding="raw", endian="little", extra=""):
    order = "<" if endian == "little" else ">"
    raw = struct.pack(order + fmt * len(values), *values)
    if encoding == "gzip":
        raw = gzip.compress(raw)
    hdr = (f"NRRD0004\ntype: {type_name}\ndimension: 3\nsizes: {dims[0]} {dims[1]} {dims[2]}\n"
           f"endian: {endian}\nencoding: {encoding}\n{extra}\n")
    with open(path, "wb") as f:
        f.write(hdr.encode() + raw)


# ------------------------------------------------------------------ success cases

def test_help_and_version(r):
    rc, out, err = r.run("--help")
    if rc != 0 or "extract" not in out or "check" not in out:
        fail("help", f"exit {rc}, {out!r}")
    for cmd in ("extract", "check", "info", "sample"):
        rc, out, err = r.run(cmd, "--help")
        if rc != 0 or f"usage: isomend {cmd}" not in out:
            fail(f"{cmd} --help", f"exit {rc}: {out[:80]!r} {err!r}")
    rc, out, err = r.run("--version")
    if rc != 0 or not out.startswith("isomend 0.") or "dmc" not in out:
        fail("version", f"exit {rc}: {out!r}")
    have_io = "slice-stack importer: yes" in out
    rc, out, err = r.run()
    if rc != 2 or "usage" not in err:
        fail("no arguments", f"exit {rc}: {err!r}")
    return have_io


def test_f1_f2_methods(r):
    """The thesis's chapter 5.2 facts through the CLI's JSON and files."""
    expect = {
        # (volume, method): (mend, durst, holes, hole_loops, nonmanifold)
        ("f1", "mc"): (0, 0, 12, 3, 0),
        ("f1", "durst"): (0, 6, 0, 0, 0),
        ("f1", "dmc"): (6, 0, 0, 0, 0),
        ("f2", "mc"): (0, 0, 0, 0, 0),
        ("f2", "durst"): (0, 2, None, None, 2),
        ("f2", "dmc"): (0, 0, 0, 0, 0),
    }
    for (vol, method), (mend, durst, holes, loops, nonman) in expect.items():
        name = f"extract {vol} {method}"
        out, err = expect_ok(r, name, ["extract", f"builtin:{vol}", "--iso", "0", "--method", method,
                                       "-o", f"{vol}_{method}.ply", "--json", f"{vol}_{method}.json"])
        j = json.load(open(r.path(f"{vol}_{method}.json")))
        for key in ("vertices", "triangles", "triangles_by_origin", "case_histogram",
                    "ambiguous_faces", "inverted_combinations", "check", "timings_ms"):
            if key not in j:
                fail(name, f"JSON lacks {key}")
        for key in ("holes", "hole_loops", "border_edges", "nonmanifold_edges",
                    "misoriented_edges", "components", "euler"):
            if key not in j["check"]:
                fail(name, f"JSON check lacks {key}")
        for key in ("read", "extract", "write"):
            if not isinstance(j["timings_ms"].get(key), (int, float)) or j["timings_ms"][key] < 0:
                fail(name, f"timings_ms.{key} missing or negative")
        if len(j["case_histogram"]) != 15 or sum(j["case_histogram"]) != 27 or j["cubes"] != 27:
            fail(name, f"case histogram {j['case_histogram']} does not cover the 27 cubes")
        o = j["triangles_by_origin"]
        if (o["mend"], o["durst"]) != (mend, durst):
            fail(name, f"triangles_by_origin {o}, expected mend {mend} durst {durst}")
        if o["table"] + o["mend"] + o["durst"] != j["triangles"]:
            fail(name, "triangles_by_origin does not add up")
        c = j["check"]
        if holes is not None and (c["holes"], c["hole_loops"]) != (holes, loops):
            fail(name, f"holes {c['holes']} in {c['hole_loops']} loops, expected {holes} in {loops}")
        if c["nonmanifold_edges"] != nonman or c["misoriented_edges"] != 0:
            fail(name, f"check {c}")
        props, verts, faces = read_ply(r.path(f"{vol}_{method}.ply"))
        if props != ["x", "y", "z", "nx", "ny", "nz"]:
            fail(name, f"PLY properties {props}")
        if len(verts) != j["vertices"] or len(faces) != j["triangles"]:
            fail(name, f"PLY has {len(verts)} vertices/{len(faces)} faces, JSON says "
                       f"{j['vertices']}/{j['triangles']}")
        # every vertex lies on the iso surface of the trilinear interpolant along its edge
        fn = f1 if vol == "f1" else f2
        for v in verts:
            x, y, z = v[:3]
            n = sum(abs(a - round(a)) > 1e-6 for a in (x, y, z))
            if n != 1:
                fail(name, f"vertex {v[:3]} is not on a grid edge")
                break
            # linear interpolation along the edge equals 0 at the vertex
            axis = [abs(a - round(a)) > 1e-6 for a in (x, y, z)].index(True)
            lo = [round(a) for a in (x, y, z)]
            lo[axis] = int(v[axis])
            hi = list(lo)
            hi[axis] += 1
            f0, f1v = fn(*lo), fn(*hi)
            t = v[axis] - lo[axis]
            if abs(f0 + t * (f1v - f0)) > 1e-4 * max(1.0, abs(f0), abs(f1v)):
                fail(name, f"vertex {v[:3]} is not at the iso crossing ({f0}, {f1v})")
                break
        # `isomend check` on the written file agrees with the extraction's check
        rc, out, err = r.run("check", f"{vol}_{method}.ply", "--json", "-")
        cj = json.loads(out)["check"]
        for key in ("holes", "nonmanifold_edges", "misoriented_edges", "border_edges", "euler"):
            if cj[key] != c[key]:
                fail(name, f"check of the file: {key} {cj[key]} != extract's {c[key]}")
        defects = c["holes"] or c["nonmanifold_edges"] or c["misoriented_edges"]
        if rc != (1 if defects else 0):
            fail(name, f"check exit {rc} with defects={bool(defects)}")


def test_formats(r):
    for ext in ("ply", "obj", "stl"):
        name = f"format {ext}"
        expect_ok(r, name, ["extract", "builtin:f1", "--iso", "0", "-o", f"fmt.{ext}", "--quiet"])
        rc, out, err = r.run("check", f"fmt.{ext}", "--json", "-")
        j = json.loads(out)["check"]
        if rc != 0 or j["holes"] or j["vertices"] != 30 or j["triangles"] != 40:
            fail(name, f"check exit {rc}: {j}")
    obj = open(r.path("fmt.obj")).read()
    if obj.count("\nv ") != 30 or obj.count("\nvn ") != 30 or "//" not in obj:
        fail("format obj", "expected 30 v, 30 vn and v//vn faces")
    size = os.path.getsize(r.path("fmt.stl"))
    if size != 84 + 50 * 40:
        fail("format stl", f"binary STL size {size}, expected {84 + 50 * 40}")
    expect_ok(r, "format upper case", ["extract", "builtin:f1", "--iso", "0", "-o", "UP.PLY", "-q"])
    expect_ok(r, "--output", ["extract", "builtin:f1", "--iso=0", "--output", "long.ply", "-q"])
    expect_ok(r, "--output=", ["extract", "builtin:f1", "--iso", "0", "--output=long2.ply", "-q"])
    if open(r.path("long.ply"), "rb").read() != open(r.path("long2.ply"), "rb").read() or \
            open(r.path("long.ply"), "rb").read() != open(r.path("fmt.ply"), "rb").read():
        fail("--output", "long forms give a different mesh")


def test_flags(r):
    base_args = ["extract", "builtin:f1", "--iso", "0", "--quiet"]
    expect_ok(r, "base", base_args + ["-o", "base.ply"])
    props, verts, faces = read_ply(r.path("base.ply"))

    # --no-normals
    expect_ok(r, "--no-normals", base_args + ["--no-normals", "-o", "nn.ply"])
    p2, v2, f2_ = read_ply(r.path("nn.ply"))
    if p2 != ["x", "y", "z"] or [v[:3] for v in v2] != [v[:3] for v in verts] or f2_ != faces:
        fail("--no-normals", f"properties {p2} or geometry differ")
    expect_ok(r, "--no-normals obj", base_args + ["--no-normals", "-o", "nn.obj"])
    if "vn " in open(r.path("nn.obj")).read():
        fail("--no-normals obj", "OBJ has vn lines")

    # --flip: same positions, negated normals, reversed winding
    expect_ok(r, "--flip", base_args + ["--flip", "-o", "flip.ply"])
    p3, v3, f3 = read_ply(r.path("flip.ply"))
    if [v[:3] for v in v3] != [v[:3] for v in verts]:
        fail("--flip", "positions differ")
    if any(abs(a[3 + k] + b[3 + k]) > 1e-6 for a, b in zip(verts, v3) for k in range(3)):
        fail("--flip", "normals not negated")
    def canonical(t):
        k = t.index(min(t))
        return tuple(t[k:]) + tuple(t[:k])
    if sorted(canonical(tuple(reversed(f))) for f in faces) != sorted(canonical(tuple(f)) for f in f3):
        fail("--flip", "triangles are not the original ones with reversed winding")

    # normals point towards lower values (F1 grows with y: normals have ny < 0 on average)
    if sum(v[4] for v in verts) >= 0:
        fail("normals", "normals do not point towards lower values of F1")

    # --pad: a closed surface, no border edges
    expect_ok(r, "--pad", base_args + ["--pad", "--json", "pad.json", "-o", "pad.ply"])
    j = json.load(open(r.path("pad.json")))
    if not j["pad"] or j["check"]["border_edges"] != 0 or j["check"]["holes"] != 0 \
            or j["check"]["euler"] % 2:
        fail("--pad", f"check {j['check']}")

    # --spacing and --origin: positions = origin + spacing * grid position
    expect_ok(r, "--spacing --origin", base_args + ["--spacing", "2,3,0.5", "--origin=10,-20,30",
                                                    "-o", "so.ply", "--json", "so.json"])
    p4, v4, f4 = read_ply(r.path("so.ply"))
    for a, b in zip(verts, v4):
        want = (10 + 2 * a[0], -20 + 3 * a[1], 30 + 0.5 * a[2])
        if any(abs(w - g) > 1e-4 for w, g in zip(want, b[:3])):
            fail("--spacing --origin", f"vertex {b[:3]} expected {want}")
            break
    j = json.load(open(r.path("so.json")))
    if j["spacing"] != [2, 3, 0.5] or j["origin"] != [10, -20, 30]:
        fail("--spacing --origin", f"JSON spacing {j['spacing']} origin {j['origin']}")
    if f4 != faces:
        fail("--spacing --origin", "connectivity changed")

    # --threads: the mesh does not depend on it
    data = None
    for t in ("0", "1", "2"):
        expect_ok(r, f"--threads {t}", ["extract", os.path.join(r.samples, "anatomical.nrrd"),
                                        "--iso", "7000", "--threads", t, "-q", "-o", f"t{t}.ply"])
        d = open(r.path(f"t{t}.ply"), "rb").read()
        if data is not None and d != data:
            fail("--threads", f"--threads {t} gives a different mesh")
        data = d

    # --pages: small or huge pages for the mesh in memory (huge by default), the same
    # file; JSON says which
    data = None
    for pages in ("small", "huge", None):
        opt = ["--pages", pages] if pages else []
        out, _ = expect_ok(r, f"--pages {pages}", ["extract", os.path.join(r.samples, "anatomical.nrrd"),
                                                   "--iso", "7000", *opt, "--json", "-",
                                                   "-q", "-o", f"p{pages}.ply"])
        d = open(r.path(f"p{pages}.ply"), "rb").read()
        if data is not None and d != data:
            fail("--pages", f"--pages {pages} gives a different mesh")
        data = d
        got = json.loads(out).get("pages")
        if got != (pages or "huge"):
            fail("--pages", f"--pages {pages}: JSON pages is {got!r}")

    # --stats: Table-2 and the triangle split
    out, err = expect_ok(r, "--stats", ["extract", "builtin:f1", "--iso", "0", "--stats", "-o", "st.ply"])
    for s in ("Case 0", "Case 3*", "Case 14", "Total cases", "Percentage",
              "34 by the marching cubes table", "+ 6 mending holes"):
        if s not in out:
            fail("--stats", f"output lacks {s!r}")
    if "continuity:" not in out or "time:" not in out:
        fail("summary", "extract prints no check summary / timings")

    # --stats with --quiet: only the statistics, nothing on stderr
    out, err = expect_ok(r, "--stats --quiet", ["extract", "builtin:f1", "--iso", "0", "--stats", "-q",
                                                "-o", "st.ply"])
    if "Total cases" not in out or "continuity:" in out or err:
        fail("--stats --quiet", f"stdout {out[:60]!r}..., stderr {err!r}")

    # --quiet alone: silent
    out, err = expect_ok(r, "--quiet", ["extract", "builtin:f1", "--iso", "0", "--quiet", "-o", "q.ply"])
    if out or err:
        fail("--quiet", f"output: {out!r} {err!r}")

    # --json -: stdout is exactly one JSON object, the text goes to stderr
    out, err = expect_ok(r, "--json -", ["extract", "builtin:f2", "--iso", "0", "--json", "-", "-o", "j.ply"])
    try:
        j = json.loads(out)
        if j["method"] != "dmc" or j["iso"] != 0 or j["iso_suggested"]:
            fail("--json -", f"method/iso: {j['method']} {j['iso']}")
    except ValueError as e:
        fail("--json -", f"stdout is not JSON: {e}: {out[:100]!r}")
    if "continuity:" not in err:
        fail("--json -", "summary not moved to stderr")


def test_sources(r):
    # --raw, both byte orders, equals the built-in volume's mesh byte for byte
    vals = grid(f1)
    with open(r.path("f1le.raw"), "wb") as f:
        f.write(struct.pack("<64f", *vals))
    with open(r.path("f1be.raw"), "wb") as f:
        f.write(struct.pack(">64f", *vals))
    with open(r.path("f1.f64"), "wb") as f:
        f.write(struct.pack("<64d", *vals))
    expect_ok(r, "builtin", ["extract", "builtin:f1", "--iso", "0", "-q", "-o", "ref.ply"])
    ref = open(r.path("ref.ply"), "rb").read()
    cases = {
        "raw le": ["f1le.raw", "--raw", "4,4,4:f32"],
        "raw le explicit": ["f1le.raw", "--raw", "4,4,4:f32:le"],
        "raw be": ["f1be.raw", "--raw", "4,4,4:f32:be"],
        "raw f64": ["f1.f64", "--raw", "4,4,4:f64"],
        "sample nrrd": ["f1.nrrd"],
        "sample nrrd gzip": ["f1gz.nrrd"],
        "nhdr detached": ["f1.nhdr"],
    }
    expect_ok(r, "sample f1", ["sample", "f1", "-o", "f1.nrrd"])
    expect_ok(r, "sample f1 gzip", ["sample", "f1", "--gzip", "-o", "f1gz.nrrd"])
    with open(r.path("f1.nhdr"), "w") as f:
        f.write("NRRD0004\ntype: float\ndimension: 3\nsizes: 4 4 4\nendian: big\nencoding: raw\n"
                "data file: f1be.raw\n")
    for name, src in cases.items():
        expect_ok(r, name, ["extract", *src, "--iso", "0", "-q", "-o", "cmp.ply"])
        if open(r.path("cmp.ply"), "rb").read() != ref:
            fail(name, "mesh differs from builtin:f1's")
    # integer types: a u8 sphere, and i16 with negative values
    n = 12
    import math
    sphere = [int(max(0, 200 - 40 * math.dist((x, y, z), (5.5, 5.5, 5.5))))
              for z in range(n) for y in range(n) for x in range(n)]
    with open(r.path("s.u8"), "wb") as f:
        f.write(bytes(sphere))
    write_nrrd(r.path("s16.nrrd"), "short", "h", (n, n, n), [v - 100 for v in sphere], "gzip", "big")
    for name, src, iso in (("raw u8", ["s.u8", "--raw", f"{n},{n},{n}:u8"], "99.5"),
                           ("nrrd i16 be gzip", ["s16.nrrd"], "-0.5")):
        expect_ok(r, name, ["extract", *src, "--iso", iso, "-q", "--json", "s.json", "-o", "s.ply"])
        j = json.load(open(r.path("s.json")))
        c = j["check"]
        if j["triangles"] == 0 or c["holes"] or c["border_edges"] or c["components"] != 1 or c["euler"] != 2:
            fail(name, f"the sphere is not one closed surface: {c}")
    if open(r.path("s.ply"), "rb").read() == b"":
        fail("integer types", "empty mesh")


def test_suggested_iso_and_info(r):
    anat = os.path.join(r.samples, "anatomical.nrrd")
    rc, out, err = r.run("info", anat, "--json", "-")
    if rc != 0:
        fail("info", f"exit {rc}: {err}")
        return
    j = json.loads(out)
    if j["dims"] != [33, 41, 25] or j["type"] != "i16" or j["min"] != -610 or j["max"] != 30393:
        fail("info", f"{j['dims']} {j['type']} {j['min']} {j['max']}")
    if j["spacing"] != [2, 2, 2] or j["spacing_from"] != ["header"] * 3 or j["origin"] != [-32, -40, -16]:
        fail("info", f"spacing {j['spacing']} from {j['spacing_from']} origin {j['origin']}")
    if sum(j["histogram"]) != j["samples"] or j["samples"] != 33 * 41 * 25:
        fail("info", "histogram does not count every sample")
    iso = j["suggested_iso"]
    if not (j["min"] < iso < j["max"]) or iso != int(iso) + 0.5:
        fail("info", f"suggested iso {iso} not strictly inside the range at a half integer")
    rc, out, err = r.run("info", anat, "--spacing", "1,1.5,3", "--origin", "5,6,7", "--json", "-")
    j2 = json.loads(out) if rc == 0 else {}
    if j2.get("spacing") != [1, 1.5, 3] or j2.get("spacing_from") != ["option"] * 3 \
            or j2.get("origin") != [5, 6, 7]:
        fail("info --spacing --origin", f"exit {rc}: {out[:300]}")
    rc, out, err = r.run("info", anat, "--quiet")
    if rc != 0 or out or err:
        fail("info --quiet", f"exit {rc}: {out!r} {err!r}")
    rc, out, err = r.run("info", os.path.join(r.work, "f1le.raw"), "--raw", "4,4,4:f32")
    if rc != 0 or "4 x 4 x 4" not in out or "f32" not in out or "value range: -5 .. 43" not in out:
        fail("info --raw", f"exit {rc}: {out!r} {err!r}")
    rc, out, err = r.run("info", anat)
    for s in ("dimensions:", "33 x 41 x 25", "sample type: i16", "value range:", "histogram",
              "spacing:", "header", "suggested iso:"):
        if s not in out:
            fail("info text", f"lacks {s!r}")
    # extract without --iso uses it and says so
    rc, out, err = r.run("extract", anat, "--pad", "--json", "a.json", "-o", "a.ply")
    ja = json.load(open(r.path("a.json")))
    if rc != 0 or not ja["iso_suggested"] or ja["iso"] != iso or "suggested" not in err:
        fail("suggested iso", f"exit {rc}, iso {ja.get('iso')} vs {iso}, stderr {err!r}")
    if ja["check"]["holes"] or ja["check"]["border_edges"] or ja["check"]["nonmanifold_edges"]:
        fail("anatomical padded dmc", f"not closed: {ja['check']}")
    # the sample's x axis points to -x: the mesh must span the world box, not a mirrored one
    props, verts, faces = read_ply(r.path("a.ply"))
    xs = [v[0] for v in verts]
    if min(xs) < -34 or max(xs) > 34:
        fail("anatomical world box", f"x range {min(xs)}..{max(xs)}")
    rc, out, err = r.run("extract", anat, "--quiet", "-o", "aq.ply")
    if rc != 0 or err:
        fail("suggested iso --quiet", f"exit {rc}, stderr {err!r}")
    # Otsu's plateau: a two-valued volume gets the level in the middle of the gap
    write_nrrd(r.path("two.nrrd"), "uint8", "B", (4, 4, 4), [0] * 32 + [100] * 32)
    rc, out, err = r.run("info", "two.nrrd", "--json", "-")
    if rc != 0 or json.loads(out)["suggested_iso"] != 50.5:
        fail("suggested iso plateau", f"exit {rc}: {out}")
    # a constant volume has no suggestion: --iso is required
    write_nrrd(r.path("const.nrrd"), "uint8", "B", (3, 3, 3), [7] * 27)
    expect_error(r, "constant volume", ["extract", "const.nrrd", "-o", "c.ply"], 2,
                 ["--iso is required", "const.nrrd"], ["c.ply"])
    rc, out, err = r.run("info", "const.nrrd")
    if rc != 0 or "none" not in out:
        fail("info constant", f"exit {rc}: {out!r}")


def test_progress_bar(r):
    """On a terminal the bar appears on stderr; --quiet silences it."""
    anat = os.path.join(r.samples, "anatomical.nrrd")
    for quiet in (False, True):
        master, slave = pty.openpty()
        args = [r.exe, "extract", anat, "--iso", "7000", "-o", "pb.ply"] + (["--quiet"] if quiet else [])
        p = subprocess.Popen(args, cwd=r.work, stdout=subprocess.PIPE, stderr=slave,
                             stdin=subprocess.DEVNULL)
        os.close(slave)
        chunks = []
        while True:
            try:
                b = os.read(master, 4096)
            except OSError:
                break
            if not b:
                break
            chunks.append(b)
        p.wait(timeout=60)
        p.stdout.close()
        os.close(master)
        tty = b"".join(chunks).decode(errors="replace")
        shown = "%" in tty and "[" in tty and "\r" in tty
        if quiet and tty:
            fail("progress --quiet", f"terminal output with --quiet: {tty!r}")
        if not quiet and not shown:
            fail("progress", f"no progress bar on the terminal: {tty!r}")
    # not a terminal: no bar, no escape codes
    rc, out, err = r.run("extract", anat, "--iso", "7000", "-o", "pb.ply")
    if "\r" in err or "\033" in err:
        fail("progress not a tty", f"bar printed to a pipe: {err!r}")


def test_interrupt(r):
    """Ctrl-C while reading or extracting: exit 130, no output, no temporary file.
    Whenever the signal lands, the invariant is: complete mesh and exit 0, or
    nothing and exit 130; several delays make sure the second case happens."""
    import signal
    import time
    # 384^3 (54 MiB): the core streams a 256^3 extraction in tens of milliseconds on a
    # quiet machine, which ended before the first signal
    n = 384
    with open(r.path("ramp.u8"), "wb") as f:
        f.write(bytes(i * 255 // (n - 1) for i in range(n)) * (n * n))   # a ramp along x
    seen = set()
    for delay in (0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.45):
        out = r.path("int.ply")
        if os.path.exists(out):
            os.unlink(out)
        p = subprocess.Popen([r.exe, "extract", "ramp.u8", "--raw", f"{n},{n},{n}:u8", "--iso", "127.5",
                              "--threads", "1", "-o", "int.ply"], cwd=r.work,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(delay)
        p.send_signal(signal.SIGINT)
        out_text, err = p.communicate(timeout=120)
        seen.add(p.returncode)
        if p.returncode == 0:
            props, verts, faces = read_ply(out)   # complete and well formed
            if len(faces) != 2 * (n - 1) * (n - 1):
                fail("interrupt", f"exit 0 but {len(faces)} faces")
        elif p.returncode == 130:
            if os.path.exists(out):
                fail("interrupt", "exit 130 but the output exists")
            if "interrupted" not in err:
                fail("interrupt", f"exit 130 without message: {err!r}")
        elif p.returncode != -signal.SIGINT:   # killed before the handler was installed
            fail("interrupt", f"exit {p.returncode}: {err!r}")
        if leftovers(r.work):
            fail("interrupt", f"temporary files left: {leftovers(r.work)}")
    if 130 not in seen:
        fail("interrupt", f"no run was interrupted cleanly (exit codes {sorted(seen)})")
    os.unlink(r.path("ramp.u8"))


def test_check_command(r):
    expect_ok(r, "check input", ["extract", "builtin:f1", "--iso", "0", "-q", "-o", "c1.ply"])
    rc, out, err = r.run("check", "c1.ply")
    if rc != 0 or "continuous" not in out:
        fail("check", f"exit {rc}: {out!r}")
    # the grid box makes the once-used edges a legitimate border ...
    rc, out, err = r.run("check", "c1.ply", "--box", "0,0,0,3,3,3", "--json", "-")
    if rc != 0 or json.loads(out)["check"]["border_edges"] != 18:
        fail("check --box grid", f"exit {rc}: {out}")
    # ... a larger box turns them into holes
    rc, out, err = r.run("check", "c1.ply", "--box=-1,-1,-1,4,4,4", "--json", "c1.json")
    j = json.load(open(r.path("c1.json")))
    if rc != 1 or j["check"]["holes"] != 18 or j["box"] != [-1, -1, -1, 4, 4, 4]:
        fail("check --box larger", f"exit {rc}: {j}")
    rc, out, err = r.run("check", "c1.ply", "--quiet")
    if rc != 0 or out or err:
        fail("check --quiet", f"exit {rc}: {out!r} {err!r}")
    # a mesh with a triangle removed has a hole -> exit 1
    props, verts, faces = read_ply(r.path("c1.ply"))
    with open(r.path("holed.obj"), "w") as f:
        for v in verts:
            f.write("v %r %r %r\n" % v[:3])
        for t in faces[1:]:
            f.write("f %d %d %d\n" % tuple(i + 1 for i in t))
    rc, out, err = r.run("check", "holed.obj", "--json", "-")
    if rc != 1 or json.loads(out)["check"]["hole_loops"] != 1:
        fail("check hole", f"exit {rc}: {out}")
    # a misoriented triangle -> exit 1
    with open(r.path("flipped.obj"), "w") as f:
        for v in verts:
            f.write("v %r %r %r\n" % v[:3])
        for k, t in enumerate(faces):
            t = tuple(reversed(t)) if k == 5 else t
            f.write("f %d %d %d\n" % tuple(i + 1 for i in t))
    rc, out, err = r.run("check", "flipped.obj", "--json", "-")
    if rc != 1 or json.loads(out)["check"]["misoriented_edges"] == 0:
        fail("check misoriented", f"exit {rc}: {out}")


# ------------------------------------------------------------------ error paths

def test_errors(r, have_io):
    ok = ["--iso", "0"]
    with open(r.path("v999.raw"), "wb") as f:
        f.write(b"\1" * 999)
    with open(r.path("v1000.raw"), "wb") as f:
        f.write(bytes(range(250)) * 4)
    os.makedirs(r.path("adir"), exist_ok=True)
    with open(r.path("afile"), "w") as f:
        f.write("x")
    expect_ok(r, "sample", ["sample", "f1", "-o", "f1.nrrd"])

    E = expect_error
    # missing files
    E(r, "missing nrrd", ["extract", "nope.nrrd", *ok, "-o", "o.ply"], 1, ["nope.nrrd", "No such file"], ["o.ply"])
    E(r, "missing raw", ["extract", "nope.raw", "--raw", "4,4,4:u8", *ok, "-o", "o.ply"], 1,
      ["nope.raw", "No such file"], ["o.ply"])
    with open(r.path("d.nhdr"), "w") as f:
        f.write("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: gone.raw\n")
    E(r, "missing detached data", ["extract", "d.nhdr", *ok, "-o", "o.ply"], 1,
      ["gone.raw", "d.nhdr"], ["o.ply"])
    E(r, "source is a folder", ["extract", "adir", "--raw", "2,2,2:u8", *ok, "-o", "o.ply"], 1,
      ["adir", "folder"], ["o.ply"])
    # size not matching --raw
    E(r, "raw size", ["extract", "v999.raw", "--raw", "10,10,10:u8", *ok, "-o", "o.ply"], 1,
      ["v999.raw", "999 bytes", "needs 1000"], ["o.ply"])
    E(r, "raw size type", ["extract", "v1000.raw", "--raw", "10,10,10:u16", *ok, "-o", "o.ply"], 1,
      ["v1000.raw", "1000 bytes", "needs 2000"], ["o.ply"])
    # bad type / bad --raw
    E(r, "raw bad type", ["extract", "v1000.raw", "--raw", "10,10,10:u32", *ok, "-o", "o.ply"], 2,
      ["--raw", "u32"], ["o.ply"])
    E(r, "raw no type", ["extract", "v1000.raw", "--raw", "10,10,10", *ok, "-o", "o.ply"], 2,
      ["--raw", "TYPE"], ["o.ply"])
    E(r, "raw bad order", ["extract", "v1000.raw", "--raw", "10,10,10:u8:middle", *ok, "-o", "o.ply"], 2,
      ["--raw", "middle"], ["o.ply"])
    E(r, "raw two dims", ["extract", "v1000.raw", "--raw", "10,100:u8", *ok, "-o", "o.ply"], 2,
      ["--raw", "three"], ["o.ply"])
    E(r, "raw four dims", ["extract", "v1000.raw", "--raw", "10,10,10,1:u8", *ok, "-o", "o.ply"], 2,
      ["--raw", "more than three"], ["o.ply"])
    E(r, "raw zero dim", ["extract", "v1000.raw", "--raw", "10,0,10:u8", *ok, "-o", "o.ply"], 2,
      ["--raw", "'0'"], ["o.ply"])
    E(r, "raw bad number", ["extract", "v1000.raw", "--raw", "10,1O,10:u8", *ok, "-o", "o.ply"], 2,
      ["--raw", "1O"], ["o.ply"])
    # bad numbers
    for flag, value, needle in (("--iso", "abc", "--iso"), ("--iso", "nan", "--iso"),
                                ("--iso", "1e999", "--iso"), ("--iso", "1.5x", "--iso"),
                                ("--spacing", "1,2", "--spacing"), ("--spacing", "1,0,1", "--spacing"),
                                ("--spacing", "1,-2,1", "--spacing"), ("--spacing", "1,2,x", "--spacing"),
                                ("--spacing", "1,2,3,4", "--spacing"), ("--origin", "a,b,c", "--origin"),
                                ("--origin", "1,2", "--origin"), ("--threads", "-1", "--threads"),
                                ("--threads", "two", "--threads"), ("--threads", "99999", "--threads"),
                                ("--pages", "big", "--pages")):
        args = ["extract", "f1.nrrd", "-o", "o.ply", flag, value]
        if flag != "--iso":
            args += ok
        E(r, f"bad {flag} {value}", args, 2, [needle, value], ["o.ply"])
    # a volume the core refuses (one slice): failure naming the source
    write_nrrd(r.path("flat.nrrd"), "float", "f", (4, 4, 1), [0.0] * 16)
    E(r, "one slice", ["extract", "flat.nrrd", *ok, "-o", "o.ply"], 1, ["flat.nrrd", "dimensions"], ["o.ply"])
    # a volume larger than the memory is streamed; one whose slices alone do not fit the
    # memory available cannot be, and is refused before allocating (a sparse file of 1 TiB,
    # four slices of 256 GiB)
    with open(r.path("huge.u8"), "wb") as f:
        f.truncate(1 << 40)
    E(r, "slices larger than memory", ["extract", "huge.u8", "--raw", "524288,524288,4:u8", *ok, "-o", "o.ply"],
      1, ["huge.u8", "streaming slices of 524288 x 524288", "memory available"], ["o.ply"])
    os.unlink(r.path("huge.u8"))
    # methods
    E(r, "unknown method", ["extract", "f1.nrrd", *ok, "--method", "marching", "-o", "o.ply"], 2,
      ["--method", "marching"], ["o.ply"])
    rc, out, err = r.run("--version")
    for m in ("facial", "gradient", "asymptotic", "tetra", "mc33"):
        if m not in out:
            E(r, f"unavailable method {m}", ["extract", "f1.nrrd", *ok, "--method", m, "-o", "o.ply"], 2,
              ["--method", m, "not implemented", "available: mc, durst, dmc"], ["o.ply"])
    # unwritable outputs
    E(r, "output folder missing", ["extract", "f1.nrrd", *ok, "-o", "no/such/dir/o.ply"], 1,
      ["no/such/dir/o.ply", "No such file"], [])
    os.makedirs(r.path("adir.ply"), exist_ok=True)
    E(r, "output is a folder", ["extract", "f1.nrrd", *ok, "-o", "adir.ply"], 1, ["adir.ply", "folder"], [])
    E(r, "output under a file", ["extract", "f1.nrrd", *ok, "-o", "afile/o.ply"], 1,
      ["afile/o.ply", "Not a directory"], [])
    if os.geteuid() != 0:
        os.makedirs(r.path("ro"), exist_ok=True)
        os.chmod(r.path("ro"), 0o555)
        E(r, "output folder read-only", ["extract", "f1.nrrd", *ok, "-o", "ro/o.ply"], 1,
          ["ro/o.ply", "Permission denied"], ["ro/o.ply"])
        os.chmod(r.path("ro"), 0o755)
    E(r, "json unwritable", ["extract", "f1.nrrd", *ok, "-o", "o.ply", "--json", "no/dir/j.json"], 1,
      ["--json", "no/dir/j.json"], ["o.ply"])
    E(r, "json same as output", ["extract", "f1.nrrd", *ok, "-o", "o.ply", "--json", "o.ply"], 2,
      ["--json", "o.ply"], ["o.ply"])
    E(r, "json empty", ["extract", "f1.nrrd", *ok, "-o", "o.ply", "--json", ""], 2, ["--json"], ["o.ply"])
    # an existing output is kept intact when the run fails
    with open(r.path("keep.ply"), "w") as f:
        f.write("previous")
    E(r, "failure keeps old output", ["extract", "v999.raw", "--raw", "10,10,10:u8", *ok, "-o", "keep.ply"], 1,
      ["v999.raw"], [])
    if open(r.path("keep.ply")).read() != "previous":
        fail("failure keeps old output", "the previous file was changed")
    # output format
    E(r, "unknown format", ["extract", "f1.nrrd", *ok, "-o", "o.xyz"], 2, ["o.xyz", ".ply"], ["o.xyz"])
    E(r, "no extension", ["extract", "f1.nrrd", *ok, "-o", "mesh"], 2, ["mesh", ".ply"], ["mesh"])
    # usage
    E(r, "missing -o", ["extract", "f1.nrrd", *ok], 2, ["-o"], [])
    E(r, "missing source", ["extract", *ok, "-o", "o.ply"], 2, ["SOURCE"], ["o.ply"])
    E(r, "unknown option", ["extract", "f1.nrrd", *ok, "--fast", "-o", "o.ply"], 2, ["--fast"], ["o.ply"])
    E(r, "unknown short option", ["extract", "f1.nrrd", *ok, "-x", "-o", "o.ply"], 2, ["-x"], ["o.ply"])
    E(r, "missing value", ["extract", "f1.nrrd", "-o", "o.ply", "--iso"], 2, ["--iso", "missing value"], ["o.ply"])
    E(r, "flag with value", ["extract", "f1.nrrd", *ok, "--pad=yes", "-o", "o.ply"], 2, ["--pad"], ["o.ply"])
    E(r, "option twice", ["extract", "f1.nrrd", *ok, "--iso", "1", "-o", "o.ply"], 2, ["--iso", "twice"], ["o.ply"])
    E(r, "check option for extract", ["extract", "f1.nrrd", *ok, "--box", "0,0,0,1,1,1", "-o", "o.ply"], 2,
      ["--box"], ["o.ply"])
    E(r, "unknown command", ["extrude", "f1.nrrd"], 2, ["extrude"], [])
    E(r, "builtin unknown", ["extract", "builtin:f3", *ok, "-o", "o.ply"], 2,
      ["builtin:f3", "builtin:f1"], ["o.ply"])
    E(r, "builtin with --raw", ["extract", "builtin:f1", "--raw", "4,4,4:f32", *ok, "-o", "o.ply"], 2,
      ["builtin:f1", "--raw"], ["o.ply"])
    if have_io:
        E(r, "stack options on nrrd", ["extract", "f1.nrrd", "--first", "2", *ok, "-o", "o.ply"], 2,
          ["f1.nrrd", "slice stacks"], ["o.ply"])
    else:
        E(r, "not nrrd without importer", ["extract", "scan.tif", *ok, "-o", "o.ply"], 2,
          ["scan.tif", "--raw"], ["o.ply"])
        E(r, "stack option without importer", ["extract", "f1.nrrd", "--first", "2", *ok, "-o", "o.ply"], 2,
          ["--first", "importer"], ["o.ply"])
    # malformed NRRD content
    with open(r.path("bad.nrrd"), "w") as f:
        f.write("NRRD0004\ntype: float\ndimension: 3\nsizes: 4 4\n\n")
    E(r, "bad nrrd header", ["extract", "bad.nrrd", *ok, "-o", "o.ply"], 1, ["bad.nrrd", "line 4", "sizes"], ["o.ply"])
    with open(r.path("notnrrd.nrrd"), "w") as f:
        f.write("hello\n")
    E(r, "not nrrd", ["extract", "notnrrd.nrrd", *ok, "-o", "o.ply"], 1, ["notnrrd.nrrd", "not a NRRD"], ["o.ply"])
    data = open(r.path("f1.nrrd"), "rb").read()
    write_nrrd(r.path("gz.nrrd"), "float", "f", (4, 4, 4), grid(f1), "gzip")
    gz = open(r.path("gz.nrrd"), "rb").read()
    with open(r.path("gzcut.nrrd"), "wb") as f:
        f.write(gz[:-20])
    E(r, "truncated gzip", ["extract", "gzcut.nrrd", *ok, "-o", "o.ply"], 1, ["gzcut.nrrd", "truncated"], ["o.ply"])
    with open(r.path("short.nrrd"), "wb") as f:
        f.write(data[:-1])
    E(r, "truncated raw nrrd", ["extract", "short.nrrd", *ok, "-o", "o.ply"], 1, ["short.nrrd", "needs 256"], ["o.ply"])

    # check
    E(r, "check missing", ["check", "none.ply"], 1, ["none.ply", "No such file"], [])
    E(r, "check format", ["check", "mesh.off"], 2, ["mesh.off", ".ply"], [])
    E(r, "check no mesh", ["check"], 2, ["MESH"], [])
    E(r, "check two meshes", ["check", "a.ply", "b.ply"], 2, ["one MESH"], [])
    with open(r.path("broken.ply"), "w") as f:
        f.write("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    E(r, "check index out of range", ["check", "broken.ply"], 1, ["broken.ply", "vertex 7"], [])
    E(r, "check bad box", ["check", "broken.ply", "--box", "0,0,0,1,1"], 2, ["--box"], [])
    E(r, "check inverted box", ["check", "broken.ply", "--box", "1,0,0,0,1,1"], 2, ["--box", "min <= max"], [])
    E(r, "check json unwritable", ["check", "broken.ply", "--json", "no/dir/c.json"], 1, ["no/dir/c.json"], [])
    # info
    E(r, "info missing", ["info", "none.nrrd"], 1, ["none.nrrd"], [])
    E(r, "info no source", ["info"], 2, ["SOURCE"], [])
    E(r, "info raw size", ["info", "v999.raw", "--raw", "10,10,10:u8"], 1, ["needs 1000"], [])
    # sample
    E(r, "sample unknown", ["sample", "f9", "-o", "s.nrrd"], 2, ["f9"], ["s.nrrd"])
    E(r, "sample not nrrd", ["sample", "f1", "-o", "sx.ply"], 2, ["sx.ply", ".nrrd"], ["sx.ply"])
    E(r, "sample no output", ["sample", "f1"], 2, ["-o"], [])
    E(r, "sample unwritable", ["sample", "f1", "-o", "no/dir/s.nrrd"], 1, ["no/dir/s.nrrd"], [])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--samples", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    if os.path.exists(a.work):
        shutil.rmtree(a.work)
    os.makedirs(a.work)
    r = Runner(os.path.abspath(a.isomend), a.work)
    r.samples = os.path.abspath(a.samples)
    have_io = test_help_and_version(r)
    test_f1_f2_methods(r)
    test_formats(r)
    test_flags(r)
    test_sources(r)
    test_suggested_iso_and_info(r)
    test_progress_bar(r)
    test_interrupt(r)
    test_check_command(r)
    test_errors(r, have_io)
    if not clitest.failures:
        shutil.rmtree(a.work)
    return clitest.summary()


if __name__ == "__main__":
    sys.exit(main())
