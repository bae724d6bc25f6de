#!/usr/bin/env python3
"""Measures every isosurface method and prints the methods table of docs/methods.md.

Runs tests/topology/methods_bench.c (target isomend_methods_bench), which
extracts the same random grids with each method and compares the meshes with
the trilinear topology oracle, then formats its JSON lines as Markdown.

Usage:
  scripts/methods_table.py                       # configure + build in build-methods-table/
  scripts/methods_table.py --bench PATH          # use an already built bench
  scripts/methods_table.py --update docs/methods.md
      (replaces the text between <!-- methods-table:begin --> and
       <!-- methods-table:end --> in that file, through a temporary file)
Options: --grids N (default 10000), --n N (grid size, default 4), --jobs N.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ORDER = ["mc", "durst", "dmc", "facial", "gradient", "asymptotic", "tetra", "mc33"]
BEGIN = "<!-- methods-table:begin -->"
END = "<!-- methods-table:end -->"


def build_bench(build_dir, jobs):
    cfg = ["cmake", "-S", ROOT, "-B", build_dir, "-DCMAKE_BUILD_TYPE=Release",
           "-DISOMEND_BUILD_CLI=OFF", "-DISOMEND_BUILD_IO=OFF", "-DISOMEND_BUILD_MESHLAB=OFF",
           "-DISOMEND_BUILD_BLENDER=OFF", "-DISOMEND_BUILD_BENCH=OFF", "-DISOMEND_PEER_TESTS=OFF"]
    subprocess.run(cfg, check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", build_dir, "-j", str(jobs), "--target",
                    "isomend_methods_bench"], check=True, stdout=subprocess.DEVNULL)
    path = os.path.join(build_dir, "tests", "topology", "isomend_methods_bench")
    if not os.path.exists(path):
        sys.exit("methods_table: the build did not produce %s" % path)
    return path


def per10k(count, grids):
    return "%g" % round(count * 10000.0 / grids, 1)


def table(rows):
    random = {r["method"]: r for r in rows if r["kind"] == "random"}
    ref = next(r for r in rows if r["kind"] == "speed_reference")
    f = {(r["kind"], r["method"]): r for r in rows if r["kind"] in ("F1", "F2")}
    missing = [m for m in ORDER if m not in random]
    if missing:
        sys.exit("methods_table: no measurement for %s" % ", ".join(missing))
    mc = random["mc"]
    grids, n = mc["grids"], mc["n"]
    out = []
    out.append("Random grids: %d grids of %d^3 samples uniform in [-1, 1], iso 0, padded "
               "(closed surfaces); counts per 10 000 grids." % (grids, n))
    out.append("")
    out.append("| method | hole loops | edges used 3+ times | non-manifold vertices "
               "| topology mismatches | triangles vs MC | time per surface cube vs MC "
               "| extraction time vs MC |")
    out.append("|---|---:|---:|---:|---:|---:|---:|---:|")
    for m in ORDER:
        r = random[m]
        cube = "%.2f" % r["cube_ratio"] if r["cube_ratio"] is not None else "n/a"
        ext = "%.2f" % r["extract_ratio"] if r["extract_ratio"] is not None else "n/a"
        out.append("| %s | %s | %s | %s | %s | %.3f | %s | %s |" % (
            m, per10k(r["hole_loops"], grids), per10k(r["multi_edges"], grids),
            per10k(r["nonmanifold_vertices"], grids), per10k(r["mismatch_grids"], grids),
            r["triangles"] / float(mc["triangles"]), cube, ext))
    out.append("")
    out.append("Time per surface cube: %d surface cubes of a smooth %d^3 field, MC's table "
               "lookup %.1f ns per cube; extraction: isomend_extract() on the same field, one "
               "thread, no normals, MC %.1f ms."
               % (ref["surface_cubes"], ref["n"], ref["mc_cube_ns"],
                  1000 * ref["extract_mc_seconds"]))
    out.append("")
    out.append("| method | F1 triangles | F1 holes | F1 3+ edges | F1 topology | F2 triangles "
               "| F2 holes | F2 3+ edges | F2 topology |")
    out.append("|---|---:|---:|---:|---|---:|---:|---:|---|")
    for m in ORDER:
        cells = []
        for k in ("F1", "F2"):
            r = f[(k, m)]
            topo = "ok" if r["topology_match"] else "chi %d (interpolant %d)" % (
                r["chi"], r["oracle_chi"])
            cells += [str(r["triangles"]), str(r["hole_loops"]), str(r["multi_edges"]), topo]
        out.append("| %s | %s |" % (m, " | ".join(cells)))
    return "\n".join(out) + "\n"


def update(path, text):
    with open(path, encoding="utf-8") as fh:
        doc = fh.read()
    if BEGIN not in doc or END not in doc:
        sys.exit("methods_table: %s has no %s ... %s markers" % (path, BEGIN, END))
    head, rest = doc.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    new = head + BEGIN + "\n" + text + END + tail
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(os.path.abspath(path)), suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(new)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", help="path of an isomend_methods_bench binary")
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build-methods-table"))
    ap.add_argument("--grids", type=int, default=10000)
    ap.add_argument("--n", type=int, default=4)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--update", help="Markdown file whose marked table to replace")
    a = ap.parse_args()
    if a.grids < 1 or not 2 <= a.n <= 64:
        sys.exit("methods_table: --grids must be >= 1 and --n in 2..64")
    bench = a.bench or build_bench(a.build_dir, a.jobs)
    if not os.access(bench, os.X_OK):
        sys.exit("methods_table: %s is not an executable" % bench)
    res = subprocess.run([bench, str(a.grids), str(a.n)], check=True, stdout=subprocess.PIPE,
                         universal_newlines=True)
    rows = [json.loads(line) for line in res.stdout.splitlines() if line.strip()]
    text = table(rows)
    if a.update:
        update(a.update, text)
    sys.stdout.write(text)


if __name__ == "__main__":
    main()
