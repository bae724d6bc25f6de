#!/usr/bin/env python3
"""`isomend extract --min-component N --smooth N [--decimate R]` on a streamed
run (--stream, or a mesh larger than --max-memory), item 4 of the streaming
issue:

- on the MRI (padded), a CT phantom and noise (hundreds of components):
  the streamed clean-up (--min-component 20, chunks of 3 layers and the
  default)
  keeps exactly the in-memory clean-up's triangles: the same
  report (components before/after, triangles and vertices removed), the same
  --json check counts, and per-component Euler characteristics equal to the
  input's less the components dropped on purpose (numpy), closed by the
  --json check, `isomend check` and vtkFeatureEdges, with VTK's component
  count;
- the streamed smoothing (--smooth 5, chunks of 3 and the default) keeps
  the input's check (components, Euler), closed by the same three checkers,
  its volume within 0.5 % of the input's (1 % on noise, whose specks are
  smaller than a band: -0.76 % with chunks of 3) by the report and
  vtkMassProperties;
- clean-up, smoothing and decimation together (--min-component 20 --smooth 3
  --decimate 0.2): closed with the cleaned components; the same bytes on 1
  and 2 threads; with isomend-mpi, `mpirun -n N` for N = 1, 2, 3 writes the
  bytes of the streamed run;
- a 128 x 128 x 14336 u16 stack (448 MiB, 8 x --max-memory 56M) cleaned,
  smoothed (--smooth 1) and decimated within the limit plus the program's
  fixed overhead (peak by wait4), closed and checked (250 s on 2 busy cores; a 128 x 128 stack
  under 32M until the smoothing's and the decimation's estimates counted what
  they hold: it needs 44.5 MiB streamed without the check, more than 48M with
  it);
- (--largest: test_postprocess_stream_largest.py; --target-triangles and
  --max-error on a streamed run: test_postprocess_stream.py, on isomend-mpi:
  test_postprocess.py).

usage: test_postprocess_stream_steps.py --isomend PATH --samples DIR --work DIR
         --peak-rss PATH [--no-memory-bounds] [--isomend-mpi PATH --mpirun PATH]
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "common"))
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True
import clitest  # noqa: E402
from clitest import fail  # noqa: E402
import test_postprocess as tp  # noqa: E402
import test_postprocess_stream as tps  # noqa: E402

MIB = 1024 * 1024
CLOSED_KEYS = ("holes", "border_edges", "nonmanifold_edges", "misoriented_edges",
               "nonmanifold_vertices")


def closed(tag, c):
    if c is None or any(c[k] for k in CLOSED_KEYS) or not c["continuous"]:
        fail(tag, f"--json check not closed: {c}")
        return False
    return True


def post(j, step):
    return ((j or {}).get("postprocess") or {}).get(step)


def test_case(exe, work, name, src, mpi, mpirun):
    base = os.path.join(work, f"{name}_base.ply")
    rc, jb, err = tps.extract(exe, work, src, [], base)
    if rc:
        fail(name, f"extract exit {rc}: {err.strip()}")
        return
    bc = jb["check"]
    _, _, _, comps = tp.independent(f"{name} input", base, 0)
    # clean-up: exactly the in-memory one
    mem = os.path.join(work, f"{name}_mem.ply")
    rc, jm, err = tps.extract(exe, work, src, ["--min-component", "20"], mem)
    if rc:
        fail(name, f"in-memory clean-up exit {rc}: {err.strip()}")
        return
    want = tp.expected_after_clean(comps, 20, 0)
    for chunk in ([], ["--smooth", "1", "--chunk-layers", "3"]):
        if chunk:  # the clean-up's counts, with a smoothing after it in chunks of 3
            tag = f"{name} --stream --min-component 20 {' '.join(chunk)}"
        else:
            tag = f"{name} --stream --min-component 20"
        out = os.path.join(work, f"{name}_clean.ply")
        rc, j, err = tps.extract(exe, work, src, ["--stream", "--min-component", "20", *chunk], out)
        if rc:
            fail(tag, f"exit {rc}: {err.strip()}")
            continue
        cs, cm = post(j, "clean"), post(jm, "clean")
        if not cs or cs.get("streamed") is not True or \
                any(cs[k] != cm[k] for k in ("components_before", "components_after",
                                             "triangles_removed", "vertices_removed")):
            fail(tag, f"clean report {cs}, in memory {cm}")
        c = j["check"]
        if closed(tag, c) and any(c[k] != jm["check"][k] for k in ("triangles", "vertices",
                                                                    "components", "euler")):
            fail(tag, f"check {c} != in memory {jm['check']}")
        tp.check_file(exe, work, tag, out, c)
        tp.independent(tag, out, 0, want)
        if not clitest.failed(tag):
            print(f"ok   {tag}: {cs['components_after']} of {cs['components_before']} components, "
                  f"{cs['triangles_removed']} triangles removed, as in memory", flush=True)
    # smoothing: the input's surface, the volume kept
    for chunk in (["--chunk-layers", "3"], []):
        tag = f"{name} --stream --smooth 5 {' '.join(chunk)}"
        out = os.path.join(work, f"{name}_smooth.ply")
        rc, j, err = tps.extract(exe, work, src, ["--stream", "--smooth", "5", *chunk], out)
        if rc:
            fail(tag, f"exit {rc}: {err.strip()}")
            continue
        s = post(j, "smooth")
        c = j["check"]
        if closed(tag, c) and any(c[k] != bc[k] for k in ("triangles", "vertices", "components",
                                                          "euler")):
            fail(tag, f"check {c} != the input's {bc}")
        tp.check_file(exe, work, tag, out, c)
        _, _, poly, _ = tp.independent(tag, out, 0, comps)
        v0 = tp.vtk_volume(tp.read_poly(base))
        v1 = tp.vtk_volume(poly)
        dv = (s["volume_after"] - s["volume_before"]) / s["volume_before"]
        tol = 0.01 if name == "noise" else 0.005  # noise: specks smaller than a band
        if not s or s.get("streamed") is not True or abs(dv) > tol or abs(v1 - v0) > tol * v0:
            fail(tag, f"smooth report {s}: volume {100 * dv:+.3f} %, VTK {v0:.6g} -> {v1:.6g}")
        elif not clitest.failed(tag):
            print(f"ok   {tag}: volume {100 * dv:+.4f} % (VTK {100 * (v1 - v0) / v0:+.4f} %), "
                  f"moved up to {s['max_displacement']:.3f}, K={s['chunk_layers']}", flush=True)
    # all three: closed, the cleaned components, the same bytes on 2 threads and N ranks
    flags = ["--min-component", "20", "--smooth", "3", "--decimate", "0.2", "--chunk-layers", "4"]
    tag = f"{name} --stream {' '.join(flags)}"
    outs = []
    for t in ("1", "2"):
        out = os.path.join(work, f"{name}_all{t}.ply")
        rc, j, err = tps.extract(exe, work, src, ["--stream", "--threads", t, *flags], out)
        if rc:
            fail(tag, f"--threads {t} exit {rc}: {err.strip()}")
            return
        outs.append(out)
        c = j["check"]
        if closed(tag, c) and (c["components"], c["euler"]) != (jm["check"]["components"],
                                                                 jm["check"]["euler"]):
            fail(tag, f"check {c}; the cleaned mesh {jm['check']}")
    tp.check_file(exe, work, tag, outs[0], j["check"])
    tp.independent(tag, outs[0], 0, want)
    if not clitest.same_file(*outs):
        fail(tag, "--threads 1 and 2: other bytes")
    elif not clitest.failed(tag):
        d = post(j, "decimate")
        print(f"ok   {tag}: {d['triangles_before']} -> {d['triangles_after']} triangles, "
              f"{j['check']['components']} components, the same bytes on 1 and 2 threads", flush=True)
    if mpi:
        for n in (1, 2, 3):
            mout = os.path.join(work, f"{name}_mpi{n}.ply")
            p = subprocess.run([mpirun, "--oversubscribe", "-n", str(n), mpi, "extract", *src, *flags,
                                "-q", "-o", mout], cwd=work, capture_output=True, text=True,
                               env=clitest.mpi_env(), timeout=300)
            if p.returncode or not clitest.same_file(outs[0], mout):
                fail(f"{tag} isomend-mpi -n {n}", f"exit {p.returncode} {p.stderr.strip()}, "
                                                   "not the streamed run's bytes")
            else:
                print(f"ok   {tag}: isomend-mpi -n {n}, the same bytes", flush=True)
                os.remove(mout)


def test_large(exe, peak_rss, work, bounds, nx=128, size_mib=56, period=48):
    """A u16 stack 8 x --max-memory SIZE, cleaned, smoothed and decimated within it."""
    t0 = time.time()
    size, limit = f"{size_mib}M", size_mib * MIB
    nz = -(-8 * limit // (nx * nx * 2))
    path = os.path.join(work, "large.raw")
    tps.large_volume(path, nx, nz, period)
    with open(path, "rb") as f, open(os.path.join(work, "large2.raw"), "wb") as g:
        g.write(f.read(2 * nx * nx * 2))
    src = [path, "--raw", f"{nx},{nx},{nz}:u16", "--iso", "1000.5", "--pad"]
    src2 = ["large2.raw", "--raw", f"{nx},{nx},2:u16", "--iso", "1000.5", "--pad"]
    flags = ["--max-memory", size, "--min-component", "50", "--smooth", "1", "--decimate", "0.1"]

    def measured(args, out):
        args = [exe, "extract", *args, "-q", "-o", out, "--json", "j.json"]
        rc, _, err, peak = clitest.run_measured(peak_rss, args, work, timeout=900)
        j = None
        if rc == 0:
            with open(os.path.join(work, "j.json")) as f:
                j = json.load(f)
        return rc, err, peak, j

    rc, err, overhead, _ = measured([*src2, "--max-memory", size], "tiny.ply")
    if rc:
        fail("large overhead", f"exit {rc}: {err.strip()}")
        return
    out = os.path.join(work, "large.ply")
    rc, err, peak, j = measured([*src, *flags], out)
    tag = (f"large {nx}x{nx}x{nz} u16 ({os.path.getsize(path) / MIB:.0f} MiB) {' '.join(flags)}")
    if rc:
        fail(tag, f"exit {rc}: {err.strip()}")
        return
    cl, sm, d = post(j, "clean"), post(j, "smooth"), post(j, "decimate")
    dv = (sm["volume_after"] - sm["volume_before"]) / sm["volume_before"]
    label = (f"{tag}: {d['triangles_before']} -> {d['triangles_after']} triangles, "
             f"{cl['components_after']} of {cl['components_before']} components kept, volume "
             f"{100 * dv:+.4f} %, K={d['chunk_layers']}, peak {peak / MIB:.1f} MiB (limit "
             f"{size_mib} MiB + overhead {overhead / MIB:.1f} MiB; in-memory estimate "
             f"{j['memory_estimate'] / MIB:.0f} MiB), {time.time() - t0:.1f} s")
    if not j["streamed"] or not all(x and x.get("streamed") for x in (cl, sm, d)):
        fail(label, "not streamed")
    if j["memory_estimate"] < 4 * limit:
        fail(label, "the in-memory estimate is below 4 x the limit: the test proves nothing")
    if bounds and peak > limit + overhead:
        fail(label, "the peak is beyond --max-memory plus the fixed overhead")
    if abs(dv) > 0.005:
        fail(label, "the smoothing changed the volume by more than 0.5 %")
    c = j["check"]
    if closed(label, c) and c["degenerate_triangles"]:
        fail(label, f"--json check {c}")
    tp.check_file(exe, work, label, out, c)
    if not clitest.failed(label):
        print(f"ok   {label}", flush=True)
    for f in (path, out, os.path.join(work, "large2.raw"), os.path.join(work, "tiny.ply")):
        if os.path.exists(f):
            os.remove(f)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--samples", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--peak-rss", required=True)
    ap.add_argument("--no-memory-bounds", action="store_true")
    ap.add_argument("--isomend-mpi")
    ap.add_argument("--mpirun", default="mpirun")
    ap.add_argument("--only", help="comma-separated case names (and 'large')")
    a = ap.parse_args()
    exe = os.path.abspath(a.isomend)
    work = os.path.abspath(a.work)
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    only = set(a.only.split(",")) if a.only else None
    mpi = a.isomend_mpi and os.path.abspath(a.isomend_mpi)
    t0 = time.time()
    anat = os.path.join(os.path.abspath(a.samples), "anatomical.nrrd")
    n = tp.ct_phantom(os.path.join(work, "ct.raw"))
    m = tp.noise(os.path.join(work, "noise.raw"), n=24)
    cases = [("mri", [anat, "--pad"]),
             ("ct", ["ct.raw", "--raw", f"{n},{n},{n}:i16", "--spacing", "0.7,0.7,1.25",
                     "--iso", "300.5", "--pad"]),
             ("noise", ["noise.raw", "--raw", f"{m},{m},{m}:u8", "--iso", "127.5", "--pad"])]
    for name, src in cases:
        if only is None or name in only:
            test_case(exe, work, name, src, mpi, a.mpirun)
    if only is None or "large" in only:
        test_large(exe, os.path.abspath(a.peak_rss), work, not a.no_memory_bounds)
    print(f"{time.time() - t0:.0f} s", flush=True)
    rc = clitest.summary(ok="postprocess stream steps: ok")
    if rc == 0:
        shutil.rmtree(work, ignore_errors=True)
    return rc


if __name__ == "__main__":
    sys.exit(main())
