#!/usr/bin/python3
"""MeshLab filter tests: MeshLab runs "Isosurface from Slice Stack (isomend)"
(and MeshLab's own "Compute Topological Measures") on stacks generated here,
and the results are compared with the `isomend extract` command line on the
same input and options.  Two ways to drive MeshLab, the same checks:

  MeshLab 2020.09 (--prefix): meshlabserver of a private prefix runs .mlx
      scripts (under with_xvfb.py, which provides $DISPLAY: it needs GLX);
  MeshLab 2021.05+ (--harness): meshlab_run_filter.cpp, linked against the
      installed MeshLab's libmeshlab-common, loads the plugins with MeshLab's
      own PluginManager and applies the filters to a MeshDocument (MeshLab
      2020.12+ has no meshlabserver); no display needed.

Usage (run by ctest):
    test_meshlab.py TEST --prefix PREFIX --cli ISOMEND --work DIR
    test_meshlab.py TEST --harness HARNESS --plugin FILE.so... --cli ISOMEND --work DIR

  counts    folder / pattern / multi-page TIFF / NRRD / raw sources, the three
            menu methods, pad, flip, spacing: MeshLab's PLY equals the CLI's
            PLY (counts, positions, normals, triangles), normals are unit, the
            log's counts and 15-case histogram equal the CLI's --json.
  topology  padded DMC of a sphere cut by the volume border and of a torus:
            MeshLab reports 0 boundary edges, two-manifold, genus 0 and 1
            (and the unpadded cut sphere has boundary edges: the measure sees
            a difference); the torus post-processed (minComponent,
            smoothIterations 5, decimateRatio 0.2): the CLI's mesh, a fifth of
            the faces, still closed with genus 1, a log line per step.
  holes     F1 (thesis Chapter 5.2) tiled by mirroring into a 7^3 volume:
            the CLI's check finds holes for mc and none for dmc, and MeshLab
            agrees: MC open, DMC closed two-manifold genus 0.
  dicom     DICOM series (tests/io/gen_dicom.py): the CLI's meshes in patient
            space, MeshLab's measure closed, errors naming the file; a
            series whose slice spacing changes part-way (issue 34) loads,
            gives the CLI's mesh with its vertices at the slices' true
            positions, and the importer's warning is in MeshLab's log.
  realdata  the ITK T1 MRI (scripts/get-test-data.sh): at the suggested level
            MeshLab counts MC's hole edges as boundary edges and finds DMC's
            result closed and two-manifold; an explicit iso 2 below the
            suggestion builds the surface at that level, not at the suggestion;
            post-processed (minComponent 50, smoothing 5, decimation 0.2): the
            CLI's mesh, a fifth of the faces, closed, the components kept.
  methods   every method the menu lists after the first three (facial,
            gradient, asymptotic, tetra, mc33 when the core builds them), by
            index: the CLI's mesh for that method, closed on the tiled F1.
  labels    a label map (a 3D Slicer .seg.nrrd of three touching structures):
            labels=all gives one layer a label, named after its segment,
            each with the CLI's (--labels all --json) vertex and face counts
            and the segment's colour on its vertices in the saved PLY;
            labels=2 alone, a colour table's names; a label not in the map,
            a fraction in the samples, a label listed twice are reported
            failures naming the reason, with no output.
  errors    bad sources and parameters: a reported failure (meshlabserver
            exit 255, the harness exit 1 with MeshLab's MLException), never an
            abort, the reason in the log, no output file; the filter is listed
            (meshlabserver's plugin dump, the harness's --list) with its
            menu text.
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
from xml.sax.saxutils import quoteattr

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from label_volumes import SEGMENTS, organs, write_seg_nrrd  # noqa: E402

FILTER = "Isosurface from Slice Stack (isomend)"
# The menu's first three methods have fixed indices; the CLI's names for them.
METHODS = ["Disambiguated MC", "Original MC", "Durst"]
CLI_METHOD = ["dmc", "mc", "durst"]
TYPES = ["u8", "i8", "u16", "i16", "i32", "f32", "f64"]

failures = []


def check(cond, what):
    if cond:
        print("  ok   " + what)
    else:
        print("  FAIL " + what)
        failures.append(what)
    return cond


# ----------------------------------------------------------------- volumes

def write_tiff_folder(folder, vol, prefix="s_"):
    import tifffile
    os.makedirs(folder, exist_ok=True)
    for k in range(vol.shape[0]):
        tifffile.imwrite(os.path.join(folder, "%s%03d.tif" % (prefix, k)), vol[k])


def write_multipage(path, vol, spacing_z=None, resolution=None):
    import tifffile
    kw = {}
    if spacing_z is not None:
        kw["imagej"] = True
        kw["metadata"] = {"spacing": spacing_z, "unit": "mm", "axes": "ZYX"}
    if resolution is not None:
        kw["resolution"] = resolution
    tifffile.imwrite(path, vol, **kw)


def write_nrrd(path, vol, spacings):
    nz, ny, nx = vol.shape
    kind = {np.dtype(np.int16): "int16", np.dtype(np.uint8): "uint8",
            np.dtype(np.float32): "float"}[vol.dtype]
    header = ("NRRD0004\ntype: %s\ndimension: 3\nsizes: %d %d %d\nspacings: %g %g %g\n"
              "encoding: raw\nendian: little\n\n" % (kind, nx, ny, nz, *spacings))
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(vol.astype(vol.dtype.newbyteorder("<")).tobytes())


def blobs(nz, ny, nx, seed=7):
    """Smooth random field with saddles: plenty of ambiguous faces."""
    rng = np.random.default_rng(seed)
    z, y, x = np.mgrid[0:nz, 0:ny, 0:nx].astype(np.float64)
    f = np.zeros((nz, ny, nx))
    for _ in range(9):
        c = rng.uniform([0, 0, 0], [nz, ny, nx])
        r2 = (z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2
        f += rng.uniform(0.6, 1.0) * np.exp(-r2 / rng.uniform(6, 20))
    f += 0.25 * np.sin(1.7 * x) * np.sin(2.1 * y) * np.sin(1.3 * z)
    f = (f - f.min()) / (f.max() - f.min())
    return f


def f1_tiled(tiles=2):
    """F1 = 4y + 4(x-z)^2 - 5 on 0..3, mirrored into (3*tiles+1)^3 samples."""
    n = 3 * tiles + 1
    idx = np.array([(i % 6) if (i % 6) <= 3 else 6 - (i % 6) for i in range(n)], float)
    z, y, x = np.meshgrid(idx, idx, idx, indexing="ij")
    return (4 * y + 4 * (x - z) ** 2 - 5).astype(np.float32)


# ------------------------------------------------------------------- runs

def mlx(params, topology=False):
    """A FilterScript calling the filter with every parameter (meshlabserver
    aborts on a missing one)."""
    p = {"source": "", "iso": 0.5, "method": 0, "spacingX": 0, "spacingY": 0, "spacingZ": 0,
         "channel": -1, "pad": True, "flipNormals": False, "rawDims": "", "rawType": 0,
         "dicomSeries": "", "dicomGridAxes": False, "minComponent": 0, "smoothIterations": 0,
         "decimateRatio": 0.0, "labels": "", "labelTable": ""}
    p.update(params)
    names = p.pop("enum_names", METHODS)
    enum_methods = " ".join('enum_val%d=%s' % (i, quoteattr(m)) for i, m in enumerate(names))
    enum_types = " ".join('enum_val%d=%s' % (i, quoteattr(t)) for i, t in enumerate(TYPES))
    b = lambda v: "true" if v else "false"
    lines = [
        "<!DOCTYPE FilterScript>", "<FilterScript>", " <filter name=%s>" % quoteattr(FILTER),
        '  <Param type="RichString" name="source" value=%s/>' % quoteattr(str(p["source"])),
        '  <Param type="RichFloat" name="iso" value="%r"/>' % float(p["iso"]),
        '  <Param type="RichEnum" name="method" value="%d" enum_cardinality="%d" %s/>'
        % (p["method"], len(names), enum_methods),
        '  <Param type="RichFloat" name="spacingX" value="%r"/>' % float(p["spacingX"]),
        '  <Param type="RichFloat" name="spacingY" value="%r"/>' % float(p["spacingY"]),
        '  <Param type="RichFloat" name="spacingZ" value="%r"/>' % float(p["spacingZ"]),
        '  <Param type="RichInt" name="channel" value="%d"/>' % p["channel"],
        '  <Param type="RichBool" name="pad" value="%s"/>' % b(p["pad"]),
        '  <Param type="RichBool" name="flipNormals" value="%s"/>' % b(p["flipNormals"]),
        '  <Param type="RichString" name="rawDims" value=%s/>' % quoteattr(str(p["rawDims"])),
        '  <Param type="RichEnum" name="rawType" value="%d" enum_cardinality="%d" %s/>'
        % (p["rawType"], len(TYPES), enum_types)]
    lines += ['  <Param type="RichString" name="dicomSeries" value=%s/>' % quoteattr(str(p["dicomSeries"])),
              '  <Param type="RichBool" name="dicomGridAxes" value="%s"/>' % b(p["dicomGridAxes"]),
              '  <Param type="RichInt" name="minComponent" value="%d"/>' % p["minComponent"],
              '  <Param type="RichInt" name="smoothIterations" value="%d"/>' % p["smoothIterations"],
              '  <Param type="RichFloat" name="decimateRatio" value="%r"/>' % float(p["decimateRatio"]),
              '  <Param type="RichString" name="labels" value=%s/>' % quoteattr(str(p["labels"])),
              '  <Param type="RichString" name="labelTable" value=%s/>' % quoteattr(str(p["labelTable"]))]
    lines.append(" </filter>")
    if topology:
        lines.append(' <filter name="Compute Topological Measures"/>')
    lines.append("</FilterScript>")
    return "\n".join(lines) + "\n"


class Runner:
    """The CLI side, shared by both MeshLab drivers."""
    fail_rc = None

    def __init__(self, cli, work):
        self.cli = cli
        self.work = work
        self.n = 0
        self.last_output = ""
        self.last_log = ""

    def isomend(self, source, args):
        """`isomend extract`; returns (json dict, PLY path)."""
        self.n += 1
        base = os.path.join(self.work, "cli%02d" % self.n)
        cmd = [self.cli, "extract", source, "-o", base + ".ply", "--json", base + ".json",
               "--quiet"] + args
        r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=120)
        if r.returncode != 0:
            raise RuntimeError("%s failed (%d): %s" % (" ".join(cmd), r.returncode,
                                                       r.stdout.decode(errors="replace")))
        with open(base + ".json") as f:
            return json.load(f), base + ".ply"

    def topology(self, log):
        return parse_topology(log)


class ServerRunner(Runner):
    """MeshLab 2020.09: meshlabserver runs .mlx scripts."""
    name = "meshlabserver"
    fail_rc = 255

    def __init__(self, prefix, cli, work):
        super().__init__(cli, work)
        self.server = os.path.join(prefix, "bin", "meshlabserver")

    def meshlab(self, params, topology=False, save=True, colors=False):
        """Runs the filter; returns (exit code, log text, output path or None)."""
        self.n += 1
        base = os.path.join(self.work, "ml%02d" % self.n)
        script, log, out = base + ".mlx", base + ".log", base + ".ply"
        with open(script, "w") as f:
            f.write(mlx(params, topology))
        for p in (log, out):
            if os.path.exists(p):
                os.remove(p)
        cmd = [self.server, "-l", log, "-s", script]
        if save:
            cmd += ["-o", out, "-m", "vn"] + (["vc"] if colors else [])
        r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=120)
        self.last_output = r.stdout.decode(errors="replace")
        text = open(log, errors="replace").read() if os.path.exists(log) else ""
        self.last_log = text
        if r.returncode != 0 and r.returncode != 255:
            print(r.stdout.decode(errors="replace")[-2000:])
        return r.returncode, text, out if os.path.exists(out) else None

    def reported_failure(self, log, reason):
        """meshlabserver prints only the log and "Problem with filter"."""
        return "Problem with filter" in log

    def listing(self):
        """The filter's entry in meshlabserver's plugin dump."""
        dump = os.path.join(self.work, "filters.txt")
        subprocess.run([self.server, "-d", dump], stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, timeout=120)
        text = open(dump, errors="replace").read() if os.path.exists(dump) else ""
        return text[text.find(FILTER):][:6000] if FILTER in text else ""


class HarnessRunner(Runner):
    """MeshLab 2021.05+: meshlab_run_filter applies the filters through
    MeshLab's own library (PluginManager, MeshDocument, io plugin)."""
    name = "meshlab_run_filter"
    fail_rc = 1

    def __init__(self, harness, plugins, cli, work):
        super().__init__(cli, work)
        self.harness = harness
        self.plugins = plugins
        self.results = []

    def run(self, steps, log=None):
        cmd = [self.harness]
        for p in self.plugins:
            cmd += ["--plugin", p]
        if log:
            cmd += ["--log", log]
        r = subprocess.run(cmd + steps, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           timeout=120)
        self.last_output = r.stdout.decode(errors="replace")
        self.results = [json.loads(l) for l in self.last_output.splitlines()
                        if l.startswith("{")]
        if r.returncode not in (0, 1):
            print(self.last_output[-2000:] + r.stderr.decode(errors="replace")[-2000:])
        return r.returncode

    def meshlab(self, params, topology=False, save=True, colors=False):
        """Runs the filter; returns (exit code, log text, output path or None);
        ``colors``: the saved PLY has the vertex colours too."""
        self.n += 1
        base = os.path.join(self.work, "ml%02d" % self.n)
        log, out = base + ".log", base + ".ply"
        for p in (log, out):
            if os.path.exists(p):
                os.remove(p)
        steps = ["--filter", FILTER]
        for k, v in params.items():
            if k == "enum_names":
                continue
            if isinstance(v, bool):
                v = "true" if v else "false"
            elif isinstance(v, float):
                v = repr(v)
            steps += ["--set", "%s=%s" % (k, v)]
        if topology:
            steps += ["--filter", "Compute Topological Measures"]
        if save:
            steps += ["--save-colors" if colors else "--save", out]
        with open(base + ".args", "w") as f:
            f.write("\n".join(steps) + "\n")
        rc = self.run(steps, log)
        text = open(log, errors="replace").read() if os.path.exists(log) else ""
        self.last_log = text
        return rc, text, out if os.path.exists(out) else None

    def topology(self, log):
        """MeshLab's own outputs of "Compute Topological Measures" (the
        values the filter returns; the log says the same)."""
        t = parse_topology(log)
        outs = [r for r in self.results if r.get("filter") == "Compute Topological Measures"]
        if not outs or not outs[-1].get("ok"):
            return t
        o = outs[-1]["outputs"]
        fromlog = dict(t)
        t.update({"V": o["vertices_number"], "E": o["edges_number"], "F": o["faces_number"],
                  "boundary_edges": o["boundary_edges"],
                  "components": o["connected_components_number"],
                  "two_manifold": o["is_mesh_two_manifold"],
                  "nonmanifold_edges": o["non_two_manifold_edges"],
                  "nonmanifold_vertices": o["non_two_manifold_vertices"]})
        if o["is_mesh_two_manifold"]:
            t.update({"holes": o["number_holes"], "genus": o["genus"]})
        same = all(fromlog.get(k) == t.get(k) for k in ("V", "E", "F", "boundary_edges",
                                                        "components", "genus", "holes"))
        check(same, "the measures MeshLab returns equal those it logs")
        return t

    def reported_failure(self, log, reason):
        """applyFilter threw MLException with the reason (what MeshLab's
        window shows); no layer was added."""
        last = self.results[-1] if self.results else {}
        return (last.get("filter") == FILTER and last.get("ok") is False
                and bool(reason) and reason in last.get("error", "") and last.get("layers") == 0)

    def listing(self):
        """The filter's name, description and parameters as MeshLab gets them."""
        rc = self.run(["--list", FILTER])
        listed = [r for r in self.results if r.get("list") == FILTER and r.get("ok")]
        if rc != 0 or not listed:
            return ""
        r = listed[0]
        check(r.get("class") == 64, "the filter's class is MeshCreation (Filters > Create New "
              "Mesh Layer), %s" % r.get("class"))
        return "\n".join([FILTER, r["info"]] + ["%s %s: %s" % (p["name"], p["label"], p["tooltip"])
                                                 for p in r["parameters"]])


# ------------------------------------------------------------------ parsing

PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
             "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
             "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
             "float64": "f8"}


def read_ply(path):
    """Binary little-endian PLY with a vertex element (scalar properties) and
    a face element (one list property of triangles).  Returns (vertex record
    array, triangles (T, 3) int64)."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert header[1].startswith("format binary_little_endian"), header[1]
    elements = []
    for line in header:
        w = line.split()
        if w[0] == "element":
            elements.append([w[1], int(w[2]), []])
        elif w[0] == "property":
            elements[-1][2].append(w[1:])
    pos = end
    verts = tris = None
    for name, count, props in elements:
        if name == "vertex":
            dt = np.dtype([(p[1], "<" + PLY_TYPES[p[0]]) for p in props])
            verts = np.frombuffer(data, dt, count, pos)
            pos += dt.itemsize * count
        elif name == "face":
            assert len(props) == 1 and props[0][0] == "list", props
            ct, it = "<" + PLY_TYPES[props[0][1]], "<" + PLY_TYPES[props[0][2]]
            dt = np.dtype([("n", ct), ("v", it, 3)])
            faces = np.frombuffer(data, dt, count, pos)
            assert (faces["n"] == 3).all(), "non-triangle face"
            tris = faces["v"].astype(np.int64)
            pos += dt.itemsize * count
        else:
            raise AssertionError("unexpected element " + name)
    return verts, tris


def last_block(log, start):
    i = log.rfind(start)
    return log[i:] if i >= 0 else ""


def parse_isomend_log(log):
    """The filter's own log lines: counts by origin and the case histogram."""
    out = {}
    m = re.search(r"vertices (\d+), triangles (\d+) \(table (\d+), Durst (\d+), mending (\d+)\)", log)
    if m:
        out["vertices"], out["triangles"], out["table"], out["durst"], out["mend"] = map(int, m.groups())
    m = re.search(r"cases \(cubes per elementary case 0\.\.14 of \d+\):((?: \d+:\d+){15})", log)
    if m:
        out["histogram"] = [int(t.split(":")[1]) for t in m.group(1).split()]
    return out


def parse_topology(log):
    """MeshLab's "Compute Topological Measures" block (the last one)."""
    block = last_block(log, "V:")
    t = {}
    m = re.search(r"V:\s*(\d+)\s+E:\s*(\d+)\s+F:\s*(\d+)", block)
    if m:
        t["V"], t["E"], t["F"] = map(int, m.groups())
    for key, pat in (("boundary_edges", r"Boundary Edges (\d+)"),
                     ("components", r"composed by (\d+) connected component"),
                     ("holes", r"Mesh has (\d+) holes"),
                     ("genus", r"Genus is (\d+)"),
                     ("nonmanifold_edges", r"Mesh has (\d+) non two manifold edges"),
                     ("nonmanifold_vertices", r"Mesh has (\d+) non two manifold vertices")):
        m = re.search(pat, block)
        if m:
            t[key] = int(m.group(1))
    t["two_manifold"] = "Mesh is two-manifold" in block
    return t


# -------------------------------------------------------------------- tests

def compare(run, label, source, ml_params, cli_args, log_expect=None):
    """The filter and `isomend extract` on the same input: identical meshes."""
    print("%s:" % label)
    params = dict(ml_params, source=source)
    rc, log, out = run.meshlab(params)
    if not check(rc == 0 and out is not None, "%s exit 0 with a PLY (rc %d)" % (run.name, rc)):
        print(log[-3000:])
        return
    ref, ref_ply = run.isomend(source, cli_args)
    v, t = read_ply(out)
    rv, rt = read_ply(ref_ply)
    check(len(v) == ref["vertices"] and len(t) == ref["triangles"],
          "vertex/triangle counts %d/%d equal the CLI's %d/%d"
          % (len(v), len(t), ref["vertices"], ref["triangles"]))
    if len(v) == len(rv) and len(t) == len(rt):
        pos = np.stack([v["x"], v["y"], v["z"]], 1)
        rpos = np.stack([rv["x"], rv["y"], rv["z"]], 1)
        check(np.array_equal(pos, rpos), "positions identical to the CLI's")
        check(np.array_equal(t, rt), "triangles identical to the CLI's")
        n = np.stack([v["nx"], v["ny"], v["nz"]], 1).astype(np.float64)
        rn = np.stack([rv["nx"], rv["ny"], rv["nz"]], 1).astype(np.float64)
        check(np.abs(n - rn).max() < 1e-6, "normals equal the CLI's")
        lengths = np.linalg.norm(n, axis=1)
        check(np.abs(lengths - 1).max() < 1e-5,
              "per-vertex normals are unit (max |len-1| %.2g)" % np.abs(lengths - 1).max())
    if log_expect:
        check(log_expect in log, "log says %r" % log_expect)
    st = parse_isomend_log(log)
    by = ref.get("triangles_by_origin", {})
    check(st.get("vertices") == ref["vertices"] and st.get("triangles") == ref["triangles"]
          and st.get("table") == by.get("table") and st.get("durst") == by.get("durst")
          and st.get("mend") == by.get("mend"),
          "log: vertices, triangles, table/Durst/mending triangles equal the CLI's json %s"
          % ({k: st.get(k) for k in ("vertices", "triangles", "table", "durst", "mend")},))
    check(st.get("histogram") == list(ref.get("case_histogram", [])),
          "log: 15-case histogram equals the CLI's")
    return ref


def test_counts(run):
    work = run.work
    f = blobs(23, 26, 29)
    u8 = np.round(f * 255).astype(np.uint8)
    folder = os.path.join(work, "stack_u8")
    write_tiff_folder(folder, u8)
    mended = 0
    for mi in range(3):
        for pad in (True, False):
            ref = compare(run, "folder u8, %s, pad %s" % (METHODS[mi], pad), folder,
                          {"iso": 127.5, "method": mi, "pad": pad},
                          ["--iso", "127.5", "--method", CLI_METHOD[mi]] + (["--pad"] if pad else []))
            if ref and mi == 0:
                mended += ref["triangles_by_origin"]["mend"]
            if mi == 0 and pad:
                # meshlabserver and the harness print the progress callback's stage texts
                out = run.last_output
                check(all(s in out for s in ("isomend: reading slices", "isomend: extracting",
                                             "isomend: done")),
                      "progress reported through MeshLab's callback (read, extract, done)")
    check(mended > 0, "the generated stack makes DMC mend (%d mending triangles)" % mended)
    compare(run, "folder u8, DMC, flipNormals", folder,
            {"iso": 127.5, "method": 0, "pad": True, "flipNormals": True},
            ["--iso", "127.5", "--method", "dmc", "--pad", "--flip"])
    compare(run, "folder u8, spacing 0.5 / 0 (= 1) / 2.25", folder,
            {"iso": 100.5, "spacingX": 0.5, "spacingY": 0, "spacingZ": 2.25},
            ["--iso", "100.5", "--pad", "--spacing", "0.5,1,2.25"])
    compare(run, "printf pattern s_%03d.tif", os.path.join(folder, "s_%03d.tif"),
            {"iso": 127.5}, ["--iso", "127.5", "--pad"])

    u16 = np.round(f * 4000).astype(np.uint16)
    multipage = os.path.join(work, "stack_u16.tif")
    write_multipage(multipage, u16, spacing_z=2.5)
    compare(run, "multi-page TIFF u16 with ImageJ spacing (metadata used by both)", multipage,
            {"iso": 2000.5, "method": 1}, ["--iso", "2000.5", "--method", "mc", "--pad"],
            log_expect="spacing 1 1 2.5 (from imagej")

    i16 = np.round(f * 3000 - 1000).astype(np.int16)
    nrrd = os.path.join(work, "vol.nrrd")
    write_nrrd(nrrd, i16, (0.8, 0.9, 1.5))
    compare(run, "NRRD i16 with spacings (negative values)", nrrd,
            {"iso": 200.5, "method": 2}, ["--iso", "200.5", "--method", "durst", "--pad"],
            log_expect="spacing 0.8 0.9 1.5 (from header, header, header)")

    # RGB slices: channel -1 is the luminance (the CLI's --channel luma),
    # channel N that channel.
    g = blobs(23, 26, 29, seed=11)
    rgb = np.stack([np.round(f * 255), np.round(g * 255), np.round((f + g) * 120)], -1).astype(np.uint8)
    rgb_folder = os.path.join(work, "stack_rgb")
    write_tiff_folder(rgb_folder, rgb)
    compare(run, "RGB folder, channel -1 (luminance)", rgb_folder,
            {"iso": 120.5, "channel": -1}, ["--iso", "120.5", "--pad", "--channel", "luma"],
            log_expect="luminance of the channels")
    compare(run, "RGB folder, channel 1", rgb_folder,
            {"iso": 120.5, "channel": 1}, ["--iso", "120.5", "--pad", "--channel", "1"])

    raw = os.path.join(work, "vol.raw")
    f.astype("<f4").tofile(raw)
    nz, ny, nx = f.shape
    compare(run, "raw f32 with rawDims/rawType", raw,
            {"iso": 0.5, "rawDims": "%d %d %d" % (nx, ny, nz), "rawType": TYPES.index("f32")},
            ["--iso", "0.5", "--pad", "--raw", "%d,%d,%d:f32" % (nx, ny, nz)])


def sphere_and_torus(n=40):
    z, y, x = np.mgrid[0:n, 0:n, 0:n].astype(np.float64)
    # a sphere whose centre is outside the box on -x: cut by the border
    r = np.sqrt((x + 3.0) ** 2 + (y - 20.2) ** 2 + (z - 19.7) ** 2)
    sphere = np.clip(200 - 10 * r + 128, 0, 255).astype(np.uint8)
    # a torus (R 11, r 4.5) fully inside
    q = np.sqrt((np.sqrt((x - 19.6) ** 2 + (y - 20.3) ** 2) - 11.0) ** 2 + (z - 20.1) ** 2)
    torus = np.clip(128 + 25 * (4.5 - q), 0, 255).astype(np.uint8)
    return sphere, torus


def test_topology(run):
    sphere, torus = sphere_and_torus()
    for name, vol, genus in (("sphere cut by the border", sphere, 0), ("torus", torus, 1)):
        folder = os.path.join(run.work, name.split()[0])
        write_tiff_folder(folder, vol)
        print("%s, padded DMC:" % name)
        rc, log, out = run.meshlab({"source": folder, "iso": 127.5, "pad": True}, topology=True)
        check(rc == 0 and out is not None, "%s exit 0 (rc %d)" % (run.name, rc))
        t = run.topology(log)
        ref, _ = run.isomend(folder, ["--iso", "127.5", "--pad"])
        check(t.get("V") == ref["vertices"] and t.get("F") == ref["triangles"],
              "MeshLab's V/F %s/%s equal the CLI's %d/%d"
              % (t.get("V"), t.get("F"), ref["vertices"], ref["triangles"]))
        check(t.get("boundary_edges") == 0, "Boundary Edges 0 (%s)" % t.get("boundary_edges"))
        check(t["two_manifold"], "Mesh is two-manifold")
        check(t.get("components") == 1, "1 connected component (%s)" % t.get("components"))
        check(t.get("genus") == genus, "Genus is %d (%s)" % (genus, t.get("genus")))
        check(t.get("holes") == 0, "0 holes (%s)" % t.get("holes"))
        if name == "torus":
            postprocess_torus(run, folder, ref, genus)
        if name.startswith("sphere"):
            print("%s, unpadded DMC (the check can fail):" % name)
            rc, log, out = run.meshlab({"source": folder, "iso": 127.5, "pad": False},
                                       topology=True)
            t = run.topology(log)
            check(rc == 0 and (t.get("boundary_edges") or 0) > 0,
                  "open where the border cuts it: Boundary Edges %s > 0" % t.get("boundary_edges"))


def postprocess_torus(run, folder, plain, genus):
    """Issue 37: the filter's post-processing (smoothIterations 5, then
    decimateRatio 0.2) gives the CLI's --smooth 5 --decimate 0.2 mesh: about a
    fifth of the plain run's faces, still closed, two-manifold, one component
    of the same genus (MeshLab's own measures), and a log line per step."""
    print("torus, padded DMC, smoothIterations 5, decimateRatio 0.2, minComponent 1:")
    rc, log, out = run.meshlab({"source": folder, "iso": 127.5, "pad": True, "smoothIterations": 5,
                                "decimateRatio": 0.2, "minComponent": 1}, topology=True)
    check(rc == 0 and out is not None, "%s exit 0 (rc %d)" % (run.name, rc))
    t = run.topology(log)
    ref, _ = run.isomend(folder, ["--iso", "127.5", "--pad", "--min-component", "1", "--smooth", "5",
                                  "--decimate", "0.2"])
    want = ref["check"]  # the counts of the CLI's final mesh
    check(t.get("V") == want["vertices"] and t.get("F") == want["triangles"],
          "MeshLab's V/F %s/%s equal the CLI's post-processed %d/%d"
          % (t.get("V"), t.get("F"), want["vertices"], want["triangles"]))
    ratio = (t.get("F") or 0) / plain["triangles"]
    check(0.18 <= ratio <= 0.22, "%s faces are %.3f of the plain run's %d (about 0.2)"
          % (t.get("F"), ratio, plain["triangles"]))
    check(t.get("boundary_edges") == 0 and t.get("two_manifold"),
          "still closed: Boundary Edges %s, two-manifold %s" % (t.get("boundary_edges"), t.get("two_manifold")))
    check(t.get("components") == 1 and t.get("genus") == genus,
          "1 component of genus %d (%s, %s)" % (genus, t.get("components"), t.get("genus")))
    d = ref["postprocess"]["decimate"]
    for line in ("clean-up (components of fewer than 1 triangles dropped): 1 of 1 components kept",
                 "smoothing (5 iterations): %d vertices moved" % ref["postprocess"]["smooth"]["moved_vertices"],
                 "decimation (ratio 0.2): %d -> %d triangles" % (d["triangles_before"], d["triangles_after"]),
                 "(target %d, reached), largest error" % d["target_triangles"]):
        check(line in log, "the log says %r" % line)
    vert, tris = read_ply(out)
    check(len(tris) == want["triangles"], "the saved PLY has %d triangles (CLI %d)"
          % (len(tris), want["triangles"]))


def test_holes(run):
    vol = f1_tiled(2)
    folder = os.path.join(run.work, "f1_tiled")
    write_tiff_folder(folder, vol)
    for mi, closed in ((1, False), (0, True), (2, True)):
        print("F1 tiled 2x2x2 by mirroring (%d^3 f32), padded, %s:" % (vol.shape[0], METHODS[mi]))
        ref, _ = run.isomend(folder, ["--iso", "0", "--pad", "--method", CLI_METHOD[mi]])
        holes = ref["check"]["holes"]
        if closed:
            check(holes == 0, "isomend check: no hole edges (%d)" % holes)
        else:
            check(holes > 0, "isomend check: hole edges %d > 0" % holes)
        rc, log, out = run.meshlab({"source": folder, "iso": 0.0, "method": mi, "pad": True},
                                   topology=True)
        check(rc == 0, "%s exit 0 (rc %d)" % (run.name, rc))
        t = run.topology(log)
        check(t.get("F") == ref["triangles"], "MeshLab's F %s equals the CLI's %d"
              % (t.get("F"), ref["triangles"]))
        if closed:
            check(t.get("boundary_edges") == 0, "MeshLab: Boundary Edges 0 (%s)" % t.get("boundary_edges"))
            check(t["two_manifold"], "MeshLab: Mesh is two-manifold")
            if mi == 0:
                check(t.get("genus") == 0 and t.get("components") == 1,
                      "MeshLab: one component of genus 0 (%s, %s)" % (t.get("components"), t.get("genus")))
        else:
            open_ = (t.get("boundary_edges") or 0) > 0 or not t["two_manifold"]
            check(open_ and t.get("boundary_edges") == holes,
                  "MeshLab: MC is open, Boundary Edges %s = isomend's hole edges %d"
                  % (t.get("boundary_edges"), holes))


def test_realdata(run, get_data):
    """The ITK T1 MRI head (Debian's insighttoolkit5-examples, fetched and
    cached by scripts/get-test-data.sh): MeshLab sees MC's holes and DMC's
    closed 2-manifold at the suggested (Otsu) level."""
    r = subprocess.run(["bash", get_data, "mri_t1_small"], stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, timeout=600)
    if not check(r.returncode == 0, "scripts/get-test-data.sh mri_t1_small (exit %d)" % r.returncode):
        print(r.stdout.decode(errors="replace")[-2000:])
        return
    root = os.environ.get("ISOMEND_TESTDATA") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "isomend")
    tiff = os.path.join(root, "mri_t1_small", "tiff")
    info = json.loads(subprocess.run([run.cli, "info", tiff, "--json", "-"], stdout=subprocess.PIPE,
                                     check=True).stdout)
    iso = info["suggested_iso"]
    refs = {}
    for mi in (1, 0):
        print("T1 MRI 128x128x62 i16, iso %g (suggested), padded, %s:" % (iso, METHODS[mi]))
        ref, _ = run.isomend(tiff, ["--iso", repr(iso), "--pad", "--method", CLI_METHOD[mi]])
        refs[mi] = ref
        rc, log, out = run.meshlab({"source": tiff, "iso": iso, "method": mi, "pad": True},
                                   topology=True, save=False)
        t = run.topology(log)
        check(rc == 0 and t.get("V") == ref["vertices"] and t.get("F") == ref["triangles"],
              "MeshLab's V/F %s/%s equal the CLI's %d/%d"
              % (t.get("V"), t.get("F"), ref["vertices"], ref["triangles"]))
        holes = ref["check"]["holes"]
        if mi == 1:
            check(holes > 0 and t.get("boundary_edges") == holes,
                  "MC: MeshLab's Boundary Edges %s = isomend's hole edges %d > 0"
                  % (t.get("boundary_edges"), holes))
        else:
            check(holes == 0 and t.get("boundary_edges") == 0 and t["two_manifold"],
                  "DMC: Boundary Edges %s, two-manifold %s, isomend hole edges %d"
                  % (t.get("boundary_edges"), t["two_manifold"], holes))

    # An iso the caller sets is the level used, never the suggestion (issue
    # 26; the filter has no "use the suggested level" switch): 2 below it.
    level = iso - 2.0
    print("T1 MRI, explicit iso %g (the suggestion is %g), padded DMC:" % (level, iso))
    ref, _ = run.isomend(tiff, ["--iso", repr(level), "--pad", "--method", "dmc"])
    check(ref["triangles"] != refs[0]["triangles"],
          "the CLI's surfaces at %g and %g differ (%d, %d triangles)"
          % (level, iso, ref["triangles"], refs[0]["triangles"]))
    rc, log, out = run.meshlab({"source": tiff, "iso": level, "method": 0, "pad": True},
                               topology=True, save=False)
    t = run.topology(log)
    check(rc == 0 and t.get("V") == ref["vertices"] and t.get("F") == ref["triangles"],
          "MeshLab's V/F %s/%s equal the CLI's %d/%d at iso %g"
          % (t.get("V"), t.get("F"), ref["vertices"], ref["triangles"], level))
    check("iso %g, padded" % level in log, "the filter's log says iso %g" % level)
    check(t.get("boundary_edges") == 0 and t["two_manifold"],
          "closed two-manifold at %g too" % level)

    # issue 37: post-processing on the MRI (minComponent 50, smoothIterations 5,
    # decimateRatio 0.2): the CLI's mesh, a fifth of the faces, still closed
    print("T1 MRI at %g, padded DMC, minComponent 50, smoothIterations 5, decimateRatio 0.2:" % iso)
    ref, _ = run.isomend(tiff, ["--iso", repr(iso), "--pad", "--method", "dmc", "--min-component", "50",
                                "--smooth", "5", "--decimate", "0.2"])
    rc, log, out = run.meshlab({"source": tiff, "iso": iso, "method": 0, "pad": True, "minComponent": 50,
                                "smoothIterations": 5, "decimateRatio": 0.2}, topology=True, save=False)
    t = run.topology(log)
    want = ref["check"]
    check(rc == 0 and t.get("V") == want["vertices"] and t.get("F") == want["triangles"],
          "MeshLab's V/F %s/%s equal the CLI's post-processed %d/%d"
          % (t.get("V"), t.get("F"), want["vertices"], want["triangles"]))
    kept = refs[0]["triangles"] - ref["postprocess"]["clean"]["triangles_removed"]
    check(0.19 <= (t.get("F") or 0) / kept <= 0.21,
          "%s faces are about 0.2 of the %d left after the clean-up" % (t.get("F"), kept))
    check(t.get("boundary_edges") == 0 and t.get("two_manifold"),
          "closed two-manifold after post-processing (Boundary Edges %s)" % t.get("boundary_edges"))
    c = ref["postprocess"]["clean"]
    check(c["components_after"] < c["components_before"] and t.get("components") == c["components_after"],
          "MeshLab counts the %d components the clean-up kept (%s)" % (c["components_after"], t.get("components")))
    for line in ("clean-up (components of fewer than 50 triangles dropped): %d of %d components kept"
                 % (c["components_after"], c["components_before"]),
                 "smoothing (5 iterations):", "decimation (ratio 0.2): ", "largest error"):
        check(line in log, "the log says %r" % line)


def test_methods(run, job):
    """Every method of the plugin's menu beyond the thesis's three (they come
    from the core's isomend_method_available()), called by index from a
    script, gives the CLI's mesh for that method name."""
    lines = subprocess.run([job, "--methods"], stdout=subprocess.PIPE, check=True,
                           universal_newlines=True).stdout.splitlines()
    menu = [l.split("\t") for l in lines if l.strip()]
    check([m[2] for m in menu[:3]] == METHODS and [m[1] for m in menu[:3]] == CLI_METHOD,
          "the menu starts with %s" % ", ".join(METHODS))
    extra = menu[3:]
    print("menu: " + ", ".join("%s %s (%s)" % tuple(m) for m in menu))
    vol = np.round(blobs(17, 19, 21, seed=5) * 255).astype(np.uint8)
    folder = os.path.join(run.work, "stack")
    write_tiff_folder(folder, vol)
    f1 = os.path.join(run.work, "f1_tiled")
    write_tiff_folder(f1, f1_tiled(2))
    for index, name, display in extra:
        params = {"method": int(index), "enum_names": [m[2] for m in menu]}
        compare(run, "method %s: %s (%s)" % (index, display, name), folder,
                dict(params, iso=127.5), ["--iso", "127.5", "--pad", "--method", name])
        print("F1 tiled, %s, padded:" % display)
        ref, _ = run.isomend(f1, ["--iso", "0", "--pad", "--method", name])
        rc, log, out = run.meshlab(dict(params, source=f1, iso=0.0), topology=True, save=False)
        t = run.topology(log)
        check(rc == 0 and t.get("F") == ref["triangles"] and t.get("boundary_edges") == 0
              and t["two_manifold"],
              "MeshLab: F %s = CLI's %d, Boundary Edges %s, two-manifold %s"
              % (t.get("F"), ref["triangles"], t.get("boundary_edges"), t["two_manifold"]))
    if not extra:
        print("this core builds only the thesis's three methods")

def expect_refusals(run, cases):
    """Each (label, params, expected reason) run fails as MeshLab reports a
    failed filter: no abort, the reason in the log, no output."""
    for label, params, expect in cases:
        print("%s:" % label)
        rc, log, out = run.meshlab(params)
        check(rc == run.fail_rc, "%s exit %d, not an abort (rc %d)" % (run.name, run.fail_rc, rc))
        m = re.search(r"isomend: error: (.*)", log)
        reason = m.group(1) if m else ""
        check(expect in reason, "log names the reason: %r" % reason)
        check(run.reported_failure(log, reason), "%s reports the failed filter" % run.name)
        check(out is None, "no output file written")


def parse_label_layers(log):
    """The adapter's 'layer "NAME": V vertices, F faces' lines (MeshLab's own
    counts of each new layer) and the job's 'label N "NAME": ... colour R G B'."""
    layers = {m.group(1): (int(m.group(2)), int(m.group(3)))
              for m in re.finditer(r'layer "([^"]*)": (\d+) vertices, (\d+) faces', log)}
    labels = {int(m.group(1)): (m.group(2), int(m.group(3)), int(m.group(4)),
                                tuple(int(c) for c in m.group(5).split()))
              for m in re.finditer(r'label (-?\d+) "([^"]*)": \d+ voxels, (\d+) vertices, '
                                   r'(\d+) triangles, colour (\d+ \d+ \d+)', log)}
    return layers, labels


def test_labels(run):
    work = run.work
    segments = SEGMENTS
    seg = os.path.join(work, "organs.seg.nrrd")
    write_seg_nrrd(seg, organs(), (0.8, 0.8, 1.5))
    out_dir = os.path.join(work, "cli_labels") + "/"
    subprocess.run([run.cli, "extract", seg, "--labels", "all", "--pad", "-o", out_dir,
                    "--json", out_dir.rstrip("/") + ".json", "--quiet"], check=True, timeout=120)
    with open(out_dir.rstrip("/") + ".json") as f:
        cli = {l["value"]: l for l in json.load(f)["labels"]}

    print("labels=all of a .seg.nrrd:")
    rc, log, out = run.meshlab({"source": seg, "labels": "all", "pad": True}, colors=True)
    check(rc == 0, "exit 0 (rc %d)" % rc)
    layers, labels = parse_label_layers(log)
    check(sorted(labels) == [1, 2, 3], "the log lists labels 1, 2, 3: %s" % sorted(labels))
    for value, name, color in segments:
        rgb = tuple(int(round(255 * c)) for c in color)
        got = labels.get(value)
        if not check(got is not None, "label %d in the log" % value):
            continue
        check(got[0] == name and got[3] == rgb, "label %d is %r, colour %s: %s" % (value, name, rgb, got))
        want = (cli[value]["vertices"], cli[value]["triangles"])
        check(got[1:3] == want, "label %d: the CLI's %d vertices, %d triangles (job: %s)"
              % (value, want[0], want[1], got[1:3]))
        check(layers.get(name) == want, "MeshLab's layer %r has the CLI's counts %s: %s"
              % (name, want, layers.get(name)))
    if check(out is not None, "the current layer (the last label) saved"):
        verts, tris = read_ply(out)
        check(len(tris) == cli[3]["triangles"], "the saved layer is Tumour's surface (%d faces)"
              % len(tris))
        if check(verts.dtype.names is not None and "red" in verts.dtype.names,
                 "the PLY has vertex colours"):
            rgb = np.stack([verts["red"], verts["green"], verts["blue"]], 1)
            check(bool((rgb == (255, 255, 0)).all()), "every vertex has Tumour's colour")

    print("labels=2, names from a colour table:")
    table = os.path.join(work, "organs.ctbl")
    with open(table, "w") as f:
        f.write("# 3D Slicer colour table\n2 Right-Kidney 12 34 56 255\n")
    rc, log, out = run.meshlab({"source": seg, "labels": "2", "labelTable": table, "pad": True})
    layers, labels = parse_label_layers(log)
    check(rc == 0 and sorted(labels) == [2], "exit 0, label 2 only: %s" % sorted(labels))
    check(labels.get(2, ("",))[0] == "Right-Kidney" and labels[2][3] == (12, 34, 56),
          "named and coloured by the table: %s" % (labels.get(2),))
    check(list(layers) == ["Right-Kidney"], "one layer, Right-Kidney: %s" % list(layers))

    fractions = os.path.join(work, "fractions.raw")
    f = organs().astype(np.float32)
    f[5, 5, 5] = 1.5
    f.tofile(fractions)
    cases = [
        ("a label not in the map", {"source": seg, "labels": "1,9"}, "label 9 is not in"),
        ("a label listed twice", {"source": seg, "labels": "2,2"}, "listed twice"),
        ("a fraction in the samples", {"source": fractions, "rawDims": "24 24 24", "rawType": 5,
                                       "labels": "all"}, "non-integer sample 1.5"),
        ("a table that is not there", {"source": seg, "labels": "all",
                                       "labelTable": os.path.join(work, "none.ctbl")}, "none.ctbl"),
    ]
    expect_refusals(run, cases)


def test_errors(run):
    work = run.work
    # the plugin is loaded and listed with its description and parameters
    block = run.listing()
    check(bool(block), "%s lists \"%s\"" % (run.name, FILTER))
    check(all(l in block for l in ("Source", "Iso level", "Method", "Spacing X", "Channel",
                                   "Pad (closed surface)", "Flip normals", "Raw dimensions",
                                   "Minimum component", "Smoothing iterations", "Decimation ratio")),
          "the listing shows the parameters with their tooltips")

    good = os.path.join(work, "good")
    write_tiff_folder(good, np.round(blobs(6, 9, 10) * 255).astype(np.uint8))
    mismatched = os.path.join(work, "mismatched")
    write_tiff_folder(mismatched, np.zeros((3, 8, 8), np.uint8))
    import tifffile
    tifffile.imwrite(os.path.join(mismatched, "s_003.tif"), np.zeros((9, 8), np.uint8))
    grey_alpha = os.path.join(work, "grey_alpha")
    os.makedirs(grey_alpha, exist_ok=True)
    for k in range(3):
        tifffile.imwrite(os.path.join(grey_alpha, "s_%d.tif" % k), np.zeros((8, 8, 2), np.uint8),
                         photometric="minisblack", planarconfig="contig", extrasamples=["unassalpha"])
    empty = os.path.join(work, "empty")
    os.makedirs(empty, exist_ok=True)
    truncated = os.path.join(work, "truncated.raw")
    np.zeros(100, np.uint8).tofile(truncated)
    not_image = os.path.join(work, "notes")
    os.makedirs(not_image, exist_ok=True)
    for k in range(3):
        with open(os.path.join(not_image, "s_%d.tif" % k), "w") as fh:
            fh.write("not a TIFF\n")

    cases = [
        ("missing folder", {"source": os.path.join(work, "no_such_stack")}, "no_such_stack"),
        ("empty folder", {"source": empty}, "empty"),
        ("slice of another size", {"source": mismatched}, "s_003.tif"),
        ("files that are not images", {"source": not_image}, "s_0.tif"),
        ("raw file shorter than rawDims", {"source": truncated, "rawDims": "10 10 10"}, "truncated.raw"),
        ("malformed rawDims", {"source": truncated, "rawDims": "10 x"}, "rawDims"),
        ("negative spacingY", {"source": good, "spacingY": -1.0}, "spacingY"),
        ("channel out of range", {"source": good, "channel": 3}, "channel"),
        ("grey + alpha with channel -1", {"source": grey_alpha}, "set the channel parameter"),
        ("no surface at the iso level", {"source": good, "iso": 1000.0}, "no surface"),
        ("empty source", {"source": ""}, "source"),
        ("decimateRatio above 1", {"source": good, "iso": 127.5, "decimateRatio": 1.5}, "decimateRatio"),
        ("negative smoothIterations", {"source": good, "iso": 127.5, "smoothIterations": -1},
         "smoothIterations"),
        ("minComponent above every component", {"source": good, "iso": 127.5, "minComponent": 100000000},
         "minComponent"),
    ]
    expect_refusals(run, cases)

    print("a good run after the failures, same folder:")
    rc, log, out = run.meshlab({"source": good, "iso": 127.5})
    check(rc == 0 and out is not None, "exit 0 with a PLY")


def test_dicom(run):
    """DICOM series (tests/io/gen_dicom.py): the filter's mesh equals the CLI's
    (axial CT, oblique CT turned into patient space, grid axes, the second of
    two series); MeshLab's own measure finds the bone closed and two-manifold;
    defects and a missing series choice fail with the file named."""
    dicom = os.path.join(run.work, "dicom")
    here = os.path.dirname(os.path.abspath(__file__))
    subprocess.run([sys.executable, os.path.join(here, "..", "io", "gen_dicom.py"), dicom,
                    os.path.join(here, "..", "..", "samples")], check=True, stdout=subprocess.DEVNULL)
    for name, ml, cli in (("ct", {}, []), ("ct_oblique", {}, []),
                          ("ct_oblique", {"dicomGridAxes": True}, ["--grid-axes"]),
                          ("two_series", {"dicomSeries": "1"}, ["--series", "1"])):
        compare(run, "DICOM %s %s" % (name, ml), os.path.join(dicom, name),
                dict(ml, iso=300.0), ["--iso", "300", "--pad"] + cli, log_expect="DICOM CT series")
        check("slices evenly spaced, gap 1.25" in run.last_log and "isomend: warning" not in run.last_log,
              "an evenly spaced series: the log says so, no warning")
    test_dicom_uneven(run, dicom)
    print("DICOM CT bone, MeshLab's topological measures:")
    rc, log, out = run.meshlab({"source": os.path.join(dicom, "ct_oblique"), "iso": 300.0}, topology=True)
    t = run.topology(log)
    check(rc == 0 and t.get("boundary_edges") == 0 and t.get("two_manifold") and t.get("holes") == 0,
          "closed two-manifold: %s" % t)
    for label, params, expect in (
            ("two series, none chosen", {"source": os.path.join(dicom, "two_series")}, "2 DICOM series"),
            ("two slices at one position", {"source": os.path.join(dicom, "duplicate")},
             "at the same position"),
            ("series 7 of a folder holding one", {"source": os.path.join(dicom, "ct"), "dicomSeries": "7"},
             "no series 7")):
        print("%s:" % label)
        rc, log, out = run.meshlab(dict(params, iso=300.0))
        m = re.search(r"isomend: error: (.*)", log)
        reason = m.group(1) if m else ""
        check(rc == run.fail_rc and expect in reason and out is None,
              "exit %s, %r in %r, no file" % (run.fail_rc, expect, reason))


def test_dicom_uneven(run, dicom):
    """Issue 34: "two_spacings" of gen_dicom.py (a CT with 2.5 mm gaps, then 5
    mm gaps: once refused) loads, and is meshed at its slices' true positions
    (cases.json's slice origins, turned into patient space), as the CLI meshes
    it; the importer's warning is in MeshLab's log at warning level."""
    name = "two_spacings"
    with open(os.path.join(dicom, "cases.json")) as fp:
        case = json.load(fp)[name]
    source = os.path.join(dicom, name)
    A = np.array(case["affine"], float)
    origins = np.array(case["slice_origins"], float) @ A[:, :3].T + A[:, 3]   # patient space
    z = origins[:, 2]
    check(case["warning"] and np.ptp(np.diff(z)) > 1.0,
          "cases.json: %s is uneven (gaps %g to %g) and warns" % (name, np.diff(z).min(), np.diff(z).max()))
    ref = compare(run, "DICOM %s (gaps %g then %g mm), bone, padded DMC" % (name, np.diff(z)[0], np.diff(z)[-1]),
                  source, {"iso": 300.0}, ["--iso", "300", "--pad"], log_expect="DICOM CT series")
    log = run.last_log
    if ref is None:
        return
    warning = ref["geometry"]["warning"]
    check(bool(warning) and not ref["geometry"]["uniform"], "the CLI warns: %r" % warning)
    check(("isomend: warning: %s: %s" % (source, warning)) in log,
          "MeshLab's log has the importer's warning: %r"
          % [l for l in log.splitlines() if "warning" in l])
    check(re.search(r"slices not evenly spaced, meshed at their positions: gaps %g to %g "
                    % (np.diff(z).min(), np.diff(z).max()), log) is not None,
          "the log reports the geometry: %r" % [l for l in log.splitlines() if "slices" in l])
    # a z spacing set for such a series makes it evenly spaced at that spacing,
    # as the CLI's --spacing does, and the importer's warning says so
    sp = case["spacing"]
    ref = compare(run, "DICOM %s with spacingZ 7 (evenly spaced at 7 mm)" % name, source,
                  {"iso": 300.0, "spacingZ": 7.0}, ["--iso", "300", "--pad", "--spacing", "%r,%r,7" % (sp[0], sp[1])],
                  log_expect="slices evenly spaced, gap 7")
    if ref is not None:
        warning = ref["geometry"]["warning"]
        check("evenly" in warning and ("isomend: warning: %s: %s" % (source, warning)) in run.last_log,
              "the log has the CLI's warning with --spacing: %r" % warning)
    print("DICOM %s, iso -1000.5 (the air's noise: every slice crosses it), unpadded:" % name)
    rc, log, out = run.meshlab({"source": source, "iso": -1000.5, "pad": False})
    if not check(rc == 0 and out is not None, "%s exit 0 with a PLY (rc %d)" % (run.name, rc)):
        return
    ref, ref_ply = run.isomend(source, ["--iso", "-1000.5"])
    v, t = read_ply(out)
    check(len(v) == ref["vertices"] and len(t) == ref["triangles"],
          "vertex/triangle counts %d/%d equal the CLI's %d/%d"
          % (len(v), len(t), ref["vertices"], ref["triangles"]))
    vz = v["z"].astype(np.float64)
    want = z.astype(np.float32).astype(np.float64)
    check(vz.min() == want[0] and vz.max() == want[-1],
          "the vertices' z span %.6g .. %.6g is the first and last slices' %.6g .. %.6g"
          % (vz.min(), vz.max(), want[0], want[-1]))
    # the vertices of edges within a slice lie at that slice's z: every slice
    # is where the series says, not on an evenly spaced grid
    hit = np.isin(want, vz)
    check(bool(hit.all()), "every slice's true z carries vertices (missing: %s)" % want[~hit])
    between = vz[~np.isin(vz, want)]
    k = np.searchsorted(want, between)
    check(bool(((k > 0) & (k < len(want))).all()), "every other vertex lies between two slices")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("test", choices=["counts", "topology", "holes", "errors", "realdata", "methods",
                                     "dicom", "labels"])
    ap.add_argument("--job", help="test_meshlab_job (methods)")
    ap.add_argument("--get-data", help="scripts/get-test-data.sh (realdata)")
    ap.add_argument("--prefix", help="MeshLab 2020.09: the private prefix with meshlabserver")
    ap.add_argument("--harness", help="MeshLab 2021.05+: meshlab_run_filter")
    ap.add_argument("--plugin", action="append", default=[],
                    help="with --harness: a plugin to load (the filter, filter_measure, io_base)")
    ap.add_argument("--cli", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    if bool(a.prefix) == bool(a.harness):
        ap.error("give --prefix (meshlabserver) or --harness")
    if a.prefix and not os.environ.get("DISPLAY"):
        print("no DISPLAY: run under with_xvfb.py or xvfb-run -a (meshlabserver needs a GLX context)")
        return 1
    if os.path.isdir(a.work):
        shutil.rmtree(a.work)
    os.makedirs(a.work)
    if a.prefix:
        run = ServerRunner(a.prefix, a.cli, a.work)
    else:
        run = HarnessRunner(a.harness, a.plugin, a.cli, a.work)
    if a.test == "realdata":
        test_realdata(run, a.get_data)
    elif a.test == "methods":
        test_methods(run, a.job)
    else:
        {"counts": test_counts, "topology": test_topology, "holes": test_holes,
         "errors": test_errors, "dicom": test_dicom, "labels": test_labels}[a.test](run)
    runs = sum(1 for f in os.listdir(a.work) if f.endswith(".mlx") or f.endswith(".args"))
    print("%d %s run(s); %s" % (runs, run.name, "FAILED: %d" % len(failures) if failures else "all ok"))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
