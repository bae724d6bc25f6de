#!/usr/bin/python3
"""isomend and vtkFlyingEdges3D side by side in one process: a check of bench.py.

What a user would do to see the speed-up for themselves, written apart from
bench.py (nothing of it is imported): one Python process, one float32 array handed
to both, vtkFlyingEdges3D geometry-only (normals, gradients, scalars off) created
and updated back to back, isomend DMC with normals through the Blender add-on's
Python wrapper (isomend.extract, the library's arrays without a copy), one
untimed full-size call of each first, then the calls alternating isomend, Flying
Edges, isomend, ...  It prints the median wall time, CPU time (user + system of
the process) and minor page faults of a call, and the ratio.

The process is run once per memory regime, as a child of this script, because the
allocator reads its settings when a process starts:

  warm     GLIBC_TUNABLES=glibc.malloc.mmap_max=0:glibc.malloc.trim_threshold=16 GiB:
           glibc keeps the memory a call frees, so the next call reuses it (bench.py's
           warm regime)
  default  no tunables: what a plain `python3 script.py` gets.  glibc maps a large
           block of its own (above M_MMAP_THRESHOLD, 128 KiB at first) and unmaps
           it on free, and trims the top of its heap above M_TRIM_THRESHOLD; but
           the first time a mapped block of up to 32 MiB is freed, it raises the
           mapping threshold to that block's size and the trim threshold to twice
           it.  From then on blocks of that size stay in the heap: whether Flying
           Edges' arrays fault in again every call depends on what the process
           freed before (0 or ~8 500 faults a call on the 256^3 sphere).
  cold     glibc's starting thresholds, fixed (glibc.malloc.mmap_threshold=131072:
           glibc.malloc.trim_threshold=131072, which stops the raise): every call
           faults its large arrays in again, as in bench.py's cold children, where
           nothing raises the thresholds before the timed calls

bench.py's warm and cold figures are the same measurements made its own way (a
child process per round, several rounds); `--compare BENCH.json` prints its
figures for the same volume and thread count beside these.

Usage:
  peer_probe.py [--field sphere|gyroid | --npy FILE --iso X] [--size N]
                [--threads N] [--calls N] [--regimes warm,default,cold] [--reuse]
                [--lib-dir DIR] [--compare BENCH.json] [--json OUT]

--reuse updates one filter again (Modified() + Update()) instead of creating one a
call.  The sphere and the gyroid are bench.py's definitions (R = 0.4 N, 16 periods),
computed here; --npy takes any saved 3D float32 array, e.g. bench.py's cached
volumes (~/.cache/isomend-bench).
"""
import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
TUNABLES = {"warm": "glibc.malloc.mmap_max=0:glibc.malloc.trim_threshold=17179869184",
            "default": None,
            "cold": "glibc.malloc.mmap_threshold=131072:glibc.malloc.trim_threshold=131072"}


def volume(args):
    import numpy as np
    if args.npy:
        a = np.load(args.npy)
        if a.ndim != 3 or a.dtype != np.float32:
            raise SystemExit("peer_probe.py: --npy %s: expected a 3D float32 array, got %s %s"
                             % (args.npy, a.dtype, a.shape))
        return np.ascontiguousarray(a), args.iso
    n = args.size
    if args.field == "sphere":  # 0.4 N - |p - c|
        c = np.arange(n, dtype=np.float32) - np.float32((n - 1) / 2)
        r = np.sqrt(c[:, None, None] ** 2 + c[None, :, None] ** 2 + c[None, None, :] ** 2)
        return (np.float32(0.4 * n) - r).astype(np.float32), 0.0
    # gyroid, 16 periods across the box
    x = (np.arange(n, dtype=np.float64) + 0.5) * (2 * np.pi * 16 / n)
    s, c = np.sin(x).astype(np.float32), np.cos(x).astype(np.float32)
    f = s[None, None, :] * c[None, :, None] + s[None, :, None] * c[:, None, None]
    f += s[:, None, None] * c[None, None, :]
    return f.astype(np.float32), 0.0


def measure(args):
    """One process: both extractors on the same array, alternating."""
    if args.threads <= (os.cpu_count() or 1):
        os.sched_setaffinity(0, set(sorted(os.sched_getaffinity(0))[:args.threads]))
    if args.lib_dir:
        os.environ["ISOMEND_LIB_DIR"] = args.lib_dir
    sys.path.insert(0, os.path.join(ROOT, "blender_addon", "isomend_import"))
    import isomend  # the add-on's wrapper
    from vtkmodules.vtkCommonCore import vtkSMPTools
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D

    a, iso = volume(args)
    vtkSMPTools.Initialize(args.threads)
    img = vtkImageData()
    img.SetDimensions(a.shape[2], a.shape[1], a.shape[0])
    scalars = numpy_to_vtk(a.reshape(-1), deep=False)
    img.GetPointData().SetScalars(scalars)

    def new_fe():
        f = vtkFlyingEdges3D()
        f.SetInputData(img)
        f.SetValue(0, iso)
        f.ComputeNormalsOff()
        f.ComputeGradientsOff()
        f.ComputeScalarsOff()
        return f
    kept = new_fe() if args.reuse else None

    def fe():
        f = kept if args.reuse else new_fe()
        f.Modified()
        f.Update()
        out = f.GetOutput()
        return out.GetNumberOfPolys(), out.GetNumberOfPoints()

    def im():
        m = isomend.extract(a, iso, method="dmc", normals=True, threads=args.threads)
        return m.triangle_count, m.vertex_count

    res = {"isomend": {}, "fe": {}}
    for name, fn in (("isomend", im), ("fe", fe)):
        res[name]["counts"] = fn()  # the warm-up call, full size
    for _ in range(args.calls):
        for name, fn in (("isomend", im), ("fe", fe)):
            ru0 = resource.getrusage(resource.RUSAGE_SELF)
            t0 = time.perf_counter()
            counts = fn()
            dt = time.perf_counter() - t0
            ru1 = resource.getrusage(resource.RUSAGE_SELF)
            if counts != res[name]["counts"]:
                raise SystemExit("peer_probe.py: %s's mesh changed between calls" % name)
            r = res[name]
            r.setdefault("times", []).append(dt)
            r.setdefault("cpu_times", []).append(ru1.ru_utime - ru0.ru_utime
                                                 + ru1.ru_stime - ru0.ru_stime)
            r.setdefault("minflt", []).append(ru1.ru_minflt - ru0.ru_minflt)
    json.dump(res, sys.stdout)


def bench_figures(path, vol, threads):
    """bench.py's results for the same volume and thread count: {(ext, regime): row}."""
    with open(path) as f:
        data = json.load(f)
    field, size = vol
    return {(r["extractor"], r.get("regime", "cold")): r for r in data["results"]
            if "median" in r and r["field"] == field and r["size"] == size
            and r["dtype"] == "f32" and r["threads"] == threads
            and r["extractor"] in ("isomend", "fe")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--field", choices=("sphere", "gyroid"), default="sphere")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--npy", help="a saved 3D float32 array instead of --field/--size")
    ap.add_argument("--iso", type=float, default=0.0, help="level for --npy (default 0)")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--calls", type=int, default=7, help="timed calls of each (default 7)")
    ap.add_argument("--regimes", default="warm,default,cold",
                    help="comma list of warm, default, cold (default: all three)")
    ap.add_argument("--reuse", action="store_true", help="one Flying Edges filter, updated")
    ap.add_argument("--lib-dir", help="folder with libisomend.so (else $ISOMEND_LIB_DIR)")
    ap.add_argument("--compare", help="bench.py --json output to print beside")
    ap.add_argument("--json", help="write the results here")
    ap.add_argument("--check", action="store_true",
                    help="exit 1 unless the regimes did what they say: Flying Edges' arrays "
                         "(64 pages or more) faulted in again in every cold call, a warm call "
                         "faulting at most 5 %% of that, "
                         "the same meshes in every regime")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.size < 4 or args.calls < 1 or args.threads < 1:
        ap.error("--size >= 4, --calls >= 1 and --threads >= 1")
    if args.npy and not os.path.exists(args.npy):
        ap.error("--npy %s does not exist" % args.npy)
    if args.child:
        measure(args)
        return 0
    regimes = args.regimes.split(",")
    if not regimes or any(g not in TUNABLES for g in regimes):
        ap.error("--regimes: a comma list of %s" % ", ".join(TUNABLES))
    if args.npy:
        name = os.path.basename(args.npy)
        vol = None
        parts = name.split("-")  # bench.py's cache: v1-<field>-<size>-f32.npy
        if len(parts) == 4 and parts[2].isdigit():
            vol = (parts[1], int(parts[2]))
    else:
        name = "%s %d³ float32" % (args.field, args.size)
        vol = (args.field, args.size)
    bench = bench_figures(args.compare, vol, args.threads) if args.compare and vol else {}
    print("%s, %d thread%s, %d calls of each after one untimed call, Flying Edges %s"
          % (name, args.threads, "" if args.threads == 1 else "s", args.calls,
             "updated again" if args.reuse else "created anew each call"))
    print("%-7s %-8s %10s %10s %9s %8s   %s" % ("", "", "wall ms", "CPU ms", "faults",
                                                "FE / is", "bench.py: wall ms, faults"))
    report = {}
    for regime in regimes:
        env = {k: v for k, v in os.environ.items() if k != "GLIBC_TUNABLES"}
        if TUNABLES[regime]:
            env["GLIBC_TUNABLES"] = TUNABLES[regime]
        cmd = [sys.executable, os.path.abspath(__file__), "--child"] + [
            x for x in sys.argv[1:] if x not in ("--child",)]
        p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, text=True)
        if p.returncode != 0:
            print("peer_probe.py: the %s process failed (exit %d)" % (regime, p.returncode),
                  file=sys.stderr)
            return 1
        res = json.loads(p.stdout)
        med = {n: {k: statistics.median(r[k]) for k in ("times", "cpu_times", "minflt")}
               for n, r in res.items()}
        report[regime] = {"results": res, "medians": med}
        for n in ("isomend", "fe"):
            m = med[n]
            ratio = "%.2f" % (med["fe"]["times"] / med["isomend"]["times"]) if n == "fe" else ""
            b, bi = bench.get((n, regime)), bench.get(("isomend", regime))
            bs = ""
            if b:
                bs = "%.1f, %.0f" % (1e3 * b["median"], b.get("faults", float("nan")))
                if n == "fe" and bi:
                    bs += " (ratio %.2f)" % (b["median"] / bi["median"])
            print("%-7s %-8s %10.1f %10.1f %9.0f %8s   %s" % (
                regime, n, 1e3 * m["times"], 1e3 * m["cpu_times"], m["minflt"], ratio, bs))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=1)
    if args.check:
        problems = []
        counts = {tuple(map(tuple, (r["results"]["isomend"]["counts"],
                                    r["results"]["fe"]["counts"]))) for r in report.values()}
        if len(counts) != 1:
            problems.append("the meshes differ between regimes: %s" % sorted(counts))
        fe = {g: r["results"]["fe"]["minflt"] for g, r in report.items()}
        if "cold" in fe and min(fe["cold"]) < 64:  # 256 KiB: its arrays were not fresh
            problems.append("cold Flying Edges calls did not fault their arrays in: %s"
                            % fe["cold"])
        elif "warm" in fe and "cold" in fe and 20 * max(fe["warm"]) > min(fe["cold"]):
            problems.append("warm Flying Edges calls faulted (%s) more than 5 %% of the cold "
                            "ones (%s)" % (fe["warm"], fe["cold"]))
        for p in problems:
            print("peer_probe.py: check: %s" % p, file=sys.stderr)
        return 1 if problems else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
