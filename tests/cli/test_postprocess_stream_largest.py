#!/usr/bin/env python3
"""`isomend extract --stream --largest K` (two passes over a scratch spool):

- on a CT phantom and noise (122 components, many of equal size: ties),
  K = 1, 2, 5 (and 40 on noise: ties) alone and with --min-component 20:
  exactly the in-memory --largest's clean-up report, --json check counts and
  the same triangles (sorted triangle corner positions, numpy), closed by the
  --json check, `isomend check` and vtkFeatureEdges (VTK's component count);
- --largest 2 with --smooth 3 --decimate 0.3: closed, 2 components, the
  same bytes on --threads 1 and 2 and with `mpirun -n 1/2/3 isomend-mpi`;
- no scratch file is left beside the output, also after a failure (an
  output folder that cannot take the spool's writes is not tested: root);
- bad values of --largest refused (exit 2, the flag named, no file).

usage: test_postprocess_stream_largest.py --isomend PATH --work DIR
         [--isomend-mpi PATH --mpirun PATH]
"""
import argparse
import os
import shutil
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "common"))
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True
import clitest  # noqa: E402
from clitest import fail  # noqa: E402
import test_postprocess as tp  # noqa: E402
import test_postprocess_stream as tps  # noqa: E402
import test_postprocess_stream_steps as tss  # noqa: E402


def corners(path):
    """The triangles as sorted rows of their corners' positions (rotated so
    the smallest corner comes first: the winding kept)."""
    v, f = clitest.read_ply_arrays(path)
    t = v[:, :3][f.astype(np.int64)]  # (n, 3, 3)
    key = t.reshape(len(t), 9)
    rows = []
    for r in key:
        c = [tuple(r[0:3]), tuple(r[3:6]), tuple(r[6:9])]
        i = min(range(3), key=lambda k: c[k])
        rows.append(c[i:] + c[:i])
    return sorted(rows)


def leftovers(work, before):
    """Files beside the outputs that were not there before (a spool, a temporary)."""
    return sorted(n for n in os.listdir(work) if n.startswith(".") and n not in before)


def test_case(exe, work, name, src, ks, mpi, mpirun):
    hidden = set(os.listdir(work))
    for mc in ([], ["--min-component", "20"]):
        for k in ks:
            flags = [*mc, "--largest", str(k)]
            tag = f"{name} --stream {' '.join(flags)}"
            mem = os.path.join(work, f"{name}_mem.ply")
            st = os.path.join(work, f"{name}_st.ply")
            rc, jm, err = tps.extract(exe, work, src, flags, mem)
            if rc:
                fail(tag, f"in memory: exit {rc}: {err.strip()}")
                continue
            rc, js, err = tps.extract(exe, work, src, ["--stream", *flags], st)
            if rc:
                fail(tag, f"exit {rc}: {err.strip()}")
                continue
            cm, cs = tss.post(jm, "clean"), tss.post(js, "clean")
            keys = ("components_before", "components_after", "triangles_removed",
                    "vertices_removed")
            if cs.get("streamed") is not True or any(cm[x] != cs[x] for x in keys):
                fail(tag, f"clean report {cs} != in memory {cm}")
            c = js["check"]
            if tss.closed(tag, c) and c != jm["check"]:
                fail(tag, f"check {c} != in memory {jm['check']}")
            if c["components"] != min(k, cm["components_after"]) or \
                    cs["components_after"] != c["components"]:
                fail(tag, f"{c['components']} components, --largest {k}")
            if corners(mem) != corners(st):
                fail(tag, "not the in-memory run's triangles")
            tp.check_file(exe, work, tag, st, c)
            tp.independent(tag, st, 0)
            if not clitest.failed(tag):
                print(f"ok   {tag}: {cs['components_after']} of {cs['components_before']} "
                      f"components, {c['triangles']} triangles, the in-memory ones", flush=True)
    # with smoothing and decimation: closed, the same bytes on threads and ranks
    flags = ["--largest", "2", "--smooth", "3", "--decimate", "0.3", "--chunk-layers", "4"]
    tag = f"{name} --stream {' '.join(flags)}"
    outs = []
    for t in ("1", "2"):
        out = os.path.join(work, f"{name}_all{t}.ply")
        rc, j, err = tps.extract(exe, work, src, ["--stream", "--threads", t, *flags], out)
        if rc:
            fail(tag, f"--threads {t} exit {rc}: {err.strip()}")
            return
        outs.append(out)
        if tss.closed(tag, j["check"]) and j["check"]["components"] != 2:
            fail(tag, f"check {j['check']}: not 2 components")
    tp.check_file(exe, work, tag, outs[0], j["check"])
    tp.independent(tag, outs[0], 0)
    if not clitest.same_file(*outs):
        fail(tag, "--threads 1 and 2: other bytes")
    elif not clitest.failed(tag):
        print(f"ok   {tag}: {j['check']['triangles']} triangles, closed, the same bytes on 1 "
              "and 2 threads", flush=True)
    if mpi:
        for n in (1, 2, 3):
            mout = os.path.join(work, f"{name}_mpi{n}.ply")
            p = subprocess.run([mpirun, "--oversubscribe", "-n", str(n), mpi, "extract", *src,
                                *flags, "-q", "-o", mout], cwd=work, capture_output=True,
                               text=True, env=clitest.mpi_env(), timeout=300)
            if p.returncode or not clitest.same_file(outs[0], mout):
                fail(f"{tag} isomend-mpi -n {n}", f"exit {p.returncode} {p.stderr.strip()}, "
                                                   "not the streamed run's bytes")
            else:
                print(f"ok   {tag}: isomend-mpi -n {n}, the same bytes", flush=True)
                os.remove(mout)
    left = leftovers(work, hidden)
    if left:
        fail(f"{name} spool", f"left beside the outputs: {left}")
    else:
        print(f"ok   {name}: no scratch file left", flush=True)


def test_errors(exe, work, src):
    hidden = set(os.listdir(work))
    for bad in ("0", "-1", "x", "1.5", ""):
        out = os.path.join(work, "bad.ply")
        rc, _, err = tps.extract(exe, work, src, ["--stream", "--largest", bad], out)
        if rc != 2 or "--largest" not in err or os.path.exists(out):
            fail(f"--largest {bad!r}", f"exit {rc}, {err.strip()!r}, file "
                                       f"{os.path.exists(out)}")
        else:
            print(f"ok   --stream --largest {bad!r}: refused ({err.strip()})", flush=True)
    # a failure after pass 1 (an --iso the volume cannot be read at): no file, no spool
    out = os.path.join(work, "missing.ply")
    rc, _, err = tps.extract(exe, work, ["no-such.raw", *src[1:]], ["--stream", "--largest", "1"],
                             out)
    if rc == 0 or os.path.exists(out) or leftovers(work, hidden):
        fail("--largest, missing source", f"exit {rc}, file {os.path.exists(out)}, "
                                          f"left {leftovers(work, hidden)}")
    else:
        print("ok   --stream --largest 1 on a missing source: no file, no scratch file",
              flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--isomend-mpi")
    ap.add_argument("--mpirun", default="mpirun")
    a = ap.parse_args()
    exe = os.path.abspath(a.isomend)
    work = os.path.abspath(a.work)
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    mpi = a.isomend_mpi and os.path.abspath(a.isomend_mpi)
    t0 = time.time()
    n = tp.ct_phantom(os.path.join(work, "ct.raw"))
    m = tp.noise(os.path.join(work, "noise.raw"), n=24)
    noise = ["noise.raw", "--raw", f"{m},{m},{m}:u8", "--iso", "127.5", "--pad"]
    test_case(exe, work, "ct", ["ct.raw", "--raw", f"{n},{n},{n}:i16", "--spacing", "0.7,0.7,1.25",
                                "--iso", "300.5", "--pad"], (1, 2, 5), mpi, a.mpirun)
    test_case(exe, work, "noise", noise, (1, 2, 5, 40), mpi, a.mpirun)
    test_errors(exe, work, noise)
    print(f"{time.time() - t0:.0f} s", flush=True)
    rc = clitest.summary(ok="postprocess stream largest: ok")
    if rc == 0:
        shutil.rmtree(work, ignore_errors=True)
    return rc


if __name__ == "__main__":
    sys.exit(main())
