#!/usr/bin/python3
"""A TIFF folder to a PLY file, end to end: isomend's default against VTK (issues 24, 35).

Runs, on one TIFF folder (generated: a CT-like phantom of 40 balls, u16, NX x NY x NZ):

  1. isomend extract: the default (the mesh streamed to the file and checked as it goes, on
     all cores but the check's), the same on all cores (--threads N), the whole mesh in memory
     (--in-memory, the default before issue 35) and the default under a --max-memory the
     volume does not fit in; PLY out: wall time, slices/s and MB/s of input, peak resident
     memory (the process's VmHWM, reported in --json); every file must be the default's
     and every run must report its continuity check;
  2. the VTK pipeline a user would write (vtkTIFFReader -> vtkFlyingEdges3D ->
     vtkPLYWriter, python3-vtk9) in its own process: wall time and peak memory (ru_maxrss
     of that process, from wait4);
  3. isomend-mpi at N = 1, 2, 4 ranks (when built), each rank under --max-memory
     --mpi-max-memory (default 192M, below the stack's size at 512 x 512 x 1024): wall time
     and the largest rank's peak, and the file must equal isomend extract's.

Each measurement is the median of --repeats runs, alternated between the tools, so that a
busy machine slows all of them alike; ratios are what matter (the table gives VTK's time
over each run's). --field busy replaces the phantom by a smooth surface with a triangle
every 3.5 samples.

usage: stream_bench.py --isomend PATH [--isomend-mpi PATH [--mpi-max-memory SIZE]]
                       [--size NX,NY,NZ] [--repeats N] [--work DIR] [--out FILE.md] [--check]
  --check   the smoke mode for ctest: tiny defaults, and a non-zero exit if a file differs
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time

import numpy as np

VTK_SCRIPT = r"""
import sys, vtk
folder, nx, ny, nz, iso, out = sys.argv[1], *map(int, sys.argv[2:5]), float(sys.argv[5]), sys.argv[6]
r = vtk.vtkTIFFReader()
r.SetFilePrefix(folder + "/s")
r.SetFilePattern("%s_%04d.tif")
r.SetDataExtent(0, nx - 1, 0, ny - 1, 0, nz - 1)
r.SetFileNameSliceOffset(0)
r.SetOrientationType(0)  # rows as stored, as isomend reads them
fe = vtk.vtkFlyingEdges3D()
fe.SetInputConnection(r.GetOutputPort())
fe.SetValue(0, iso)
fe.ComputeNormalsOn()
w = vtk.vtkPLYWriter()
w.SetInputConnection(fe.GetOutputPort())
w.SetFileName(out)
w.SetFileTypeToBinary()
if not w.Write():
    sys.exit("vtkPLYWriter failed")
print(fe.GetOutput().GetNumberOfPolys())
"""


def make_stack(folder, nx, ny, nz, seed=3):
    """A CT-like phantom, u16, one TIFF per slice (s_0000.tif ...): 40 balls of 1000 over
    a background of 0, plus a little noise (+-60), generated slice by slice."""
    import tifffile
    os.makedirs(folder, exist_ok=True)
    rng = np.random.default_rng(seed)
    scale = min(nx, ny, nz)
    balls = [(rng.uniform(0, nx), rng.uniform(0, ny), rng.uniform(0, nz),
              rng.uniform(0.04, 0.12) * scale) for _ in range(40)]
    y, x = np.mgrid[0:ny, 0:nx].astype(np.float32)
    for k in range(nz):
        a = np.zeros((ny, nx), np.float32)
        for bx, by, bz, r in balls:
            dz = k - bz
            if abs(dz) < r:
                a[(x - bx) ** 2 + (y - by) ** 2 < r * r - dz * dz] = 1000
        a += rng.uniform(-60, 60, size=a.shape).astype(np.float32) + 100
        tifffile.imwrite(os.path.join(folder, "s_%04d.tif" % k), a.astype(np.uint16))


def make_busy_stack(folder, nx, ny, nz):
    """A busy smooth surface, u16 (test_stream_memory.py's field): about one triangle
    for every 3.5 samples at iso 1000."""
    import tifffile
    os.makedirs(folder, exist_ok=True)
    x = np.arange(nx, dtype=np.float32)[None, :]
    y = np.arange(ny, dtype=np.float32)[:, None]
    for k in range(nz):
        a = 1000 + 800 * np.sin(x * 0.21 + k * 0.05) * np.cos(y * 0.15) + 600 * np.sin(k * 0.12 + y * 0.06)
        tifffile.imwrite(os.path.join(folder, "s_%04d.tif" % k), a.astype(np.uint16))


def timed(cmd, env=None):
    """(seconds, stdout, stderr, exit code); isomend reports its own peak in --json."""
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    return time.perf_counter() - t0, p.stdout, p.stderr, p.returncode


def vtk_run(script, folder, nx, ny, nz, iso, out):
    """The VTK pipeline in its own process: (seconds, peak RSS bytes from wait4, ...)."""
    t0 = time.perf_counter()
    p = subprocess.Popen(["/usr/bin/python3", script, folder, str(nx), str(ny), str(nz), str(iso), out],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(p.pid, 0)
    t = time.perf_counter() - t0
    out_text = p.stdout.read()
    err = p.stderr.read()
    rc = os.waitstatus_to_exitcode(status)
    return t, usage.ru_maxrss * 1024, out_text, err, rc


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--isomend-mpi")
    ap.add_argument("--mpirun", default=shutil.which("mpirun") or "mpirun")
    ap.add_argument("--mpi-max-memory", default="192M", help="each rank's --max-memory")
    ap.add_argument("--size", default=None, help="NX,NY,NZ (default 512,512,256; --check 64,48,40)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--work", default="/tmp/isomend_stream_bench")
    ap.add_argument("--out")
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--field", choices=("phantom", "busy"), default="phantom",
                    help="phantom: 40 balls over noise (a CT); busy: a smooth surface with "
                         "a triangle every 3.5 samples")
    a = ap.parse_args()
    nx, ny, nz = map(int, (a.size or ("64,48,40" if a.check else "512,512,256")).split(","))
    if a.check:
        a.repeats = 1
    shutil.rmtree(a.work, ignore_errors=True)
    folder = os.path.join(a.work, "stack")
    if a.field == "busy":
        make_busy_stack(folder, nx, ny, nz)
        iso = 1000.5
    else:
        make_stack(folder, nx, ny, nz)
        iso = 600.5
    mb = nx * ny * nz * 2 / 1e6
    exe = os.path.abspath(a.isomend)
    base = [exe, "extract", folder, "--iso", str(iso), "-q", "--json", "-"]
    # a limit the volume does not fit in, streaming does: slices read one by one
    probe = subprocess.run(base + ["-o", os.path.join(a.work, "probe.ply")], capture_output=True, text=True)
    if probe.returncode:
        sys.exit("isomend extract failed: " + probe.stderr)
    j = json.loads(probe.stdout)
    limit = str(max(j["memory_streaming"] + (64 << 20), nx * ny * nz * 2 // 2))
    # the default (the mesh streamed to the file and checked on the way, all cores but
    # the check's), on all cores, the whole mesh in memory (--in-memory: checked, then
    # written), the default under a --max-memory the volume does not fit in, and VTK's
    # pipeline
    cores = str(os.cpu_count() or 1)
    runs = {"default": [], "all cores": [], "in memory": [], "max-memory": [], "vtk": []}
    mpi_ns = [1, 2, 4] if a.isomend_mpi else []
    for n in mpi_ns:
        runs[f"mpi {n}"] = []
    script = os.path.join(a.work, "vtk_pipeline.py")
    with open(script, "w") as f:
        f.write(VTK_SCRIPT)
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}  # hwloc's GL plugin, see tests/mpi
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", HWLOC_COMPONENTS="-gl")
    failures = []
    ref = os.path.join(a.work, "default.ply")
    for _ in range(a.repeats):
        for name in runs:
            out = os.path.join(a.work, name.replace(" ", "_").replace(",", "") + ".ply")
            if name == "vtk":
                t, peak, txt, err, rc = vtk_run(script, folder, nx, ny, nz, iso, out)
                if rc:
                    failures.append("vtk: " + err[-300:])
                    continue
                runs[name].append((t, peak, int(txt.split()[-1]), float("nan")))
                continue
            if name.startswith("mpi"):
                n = int(name.split()[1])
                cmd = [a.mpirun, "--oversubscribe", "-n", str(n), os.path.abspath(a.isomend_mpi), "extract",
                       folder, "--iso", str(iso), "-q", "--json", "-", "-o", out]
                if not a.check:  # the smoke mode's tiny stack needs less than a rank's bound
                    cmd += ["--max-memory", a.mpi_max_memory]
            else:
                cmd = base + ["-o", out] + {"max-memory": ["--max-memory", limit],
                                            "in memory": ["--in-memory"],
                                            "all cores": ["--threads", cores]}.get(name, [])
            t, txt, err, rc = timed(cmd, env=env)
            if rc:
                failures.append(f"{name}: {err[-300:]}")
                continue
            r = json.loads(txt)
            if not name.startswith("mpi") and (r["streamed"] != (name != "in memory") or
                                                r["check"] is None):
                failures.append(f"{name}: streamed {r['streamed']}, check {r['check']}")
            tm = r["timings_ms"]
            runs[name].append((t, r["peak_memory"], r["triangles"],
                               (tm["read"] + tm["extract"] + tm["write"]) / 1e3))
            if name != "default" and open(out, "rb").read() != open(ref, "rb").read():
                failures.append(f"{name}: the file differs from the default run's")
    rows = []
    t_vtk = statistics.median(x[0] for x in runs["vtk"]) if runs["vtk"] else float("nan")
    for name, xs in runs.items():
        if not xs:
            continue
        t = statistics.median(x[0] for x in xs)
        peak = max(x[1] for x in xs)
        label = name
        work = statistics.median(x[3] for x in xs)
        rows.append(f"| {label} | {t:.2f} | {t_vtk / t:.2f} | {work:.2f} | {nz / t:.0f} | "
                    f"{mb / t:.1f} | {peak / 2 ** 20:.0f} | {xs[0][2]} |")
    text = (f"Stack {nx}x{ny}x{nz} u16 ({mb:.1f} MB, {nz} TIFF files), iso {iso}, "
            f"{a.repeats} run(s), median wall time; peak = VmHWM (isomend's --json, largest rank) "
            f"or ru_maxrss (VTK's process); max-memory: the default under --max-memory "
            f"{int(limit) / 2 ** 20:.0f} MiB"
            + (f", each MPI rank under --max-memory {a.mpi_max_memory}" if mpi_ns and not a.check else "")
            + "\n\n"
            "| run | s | VTK's time / this | read+extract+write s | slices/s | MB/s in | peak MiB | triangles |\n"
            "|---|---|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n"
            "\nread+extract+write: isomend's own timings (--json), without the process start "
            "and, in memory, the continuity check; a streamed run's extract includes its writes "
            "and its check. Every isomend file is the default run's, byte for byte, and every "
            "isomend run reports its continuity check.\n")
    print(text)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text)
    for fl in failures:
        print("FAIL " + fl, file=sys.stderr)
    if a.check:
        if failures:
            return 1
        print("stream bench: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
