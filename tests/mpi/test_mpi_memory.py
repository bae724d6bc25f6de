#!/usr/bin/env python3
"""`mpirun -n N isomend-mpi extract --max-memory SIZE`: every rank within SIZE, same bytes.

A 512 x 512 x 384 u16 raw volume with a busy, smooth surface (29 M
triangles; in memory `isomend extract` peaks at about 0.9 GiB, measured
here: at least 4 x SIZE; it was 1.6-1.9 GiB at 256 slices while the
in-memory check sorted every edge) is extracted by `isomend extract --max-memory SIZE` (streamed: the
in-memory run's bytes, tests/cli/test_stream_memory.py) and by isomend-mpi
on N = 1, 2 and 3 ranks (mpirun --oversubscribe) with the same limit:

- the file is the same, byte for byte (PLY for every N, STL for N = 2);
- the peak resident memory, measured here (wait4's ru_maxrss of mpirun,
  the largest of mpirun's and its ranks', through tests/common/peak_rss.c)
  and reported by the program (JSON peak_memory, the largest rank's
  VmHWM), is within SIZE plus the fixed overhead of N ranks, measured the
  same way on the first two slices of the volume (the code, Open MPI's
  libraries, transports and buffers);
- on the first 64 slices the peak is the same within 4 MiB: a rank's memory
  does not depend on the length of its slab;
- a SIZE below what a rank needs is refused (exit 2, naming --max-memory).

Not for the sanitizers (their shadow memory counts as resident).

usage: test_mpi_memory.py --isomend PATH --isomend-mpi PATH --mpirun PATH --peak-rss PATH --work DIR
"""
import argparse
import json
import os
import shutil
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import clitest  # noqa: E402
from clitest import fail  # noqa: E402

MIB = 1024 * 1024
NX, NY, NZ = 512, 512, 384
ISO = "1000"
SIZE = "192M"
ENV = clitest.mpi_env()


class Runs:
    def __init__(self, a):
        self.exe = os.path.abspath(a.isomend)
        self.mpi = os.path.abspath(a.isomend_mpi)
        self.mpirun = a.mpirun
        self.peak_rss = os.path.abspath(a.peak_rss)
        self.work = a.work

    def source(self, nz):
        return [f"v{'' if nz == NZ else nz}.raw", "--raw", f"{NX},{NY},{nz}:u16"]

    def _json(self, rc):
        if rc:
            return None
        with open(os.path.join(self.work, "j.json")) as f:
            return json.load(f)

    def single(self, nz, out, size=SIZE, extra=()):
        args = [self.exe, "extract", *self.source(nz), "--iso", ISO, "-o", out, "-q",
                "--json", "j.json", "--max-memory", size, *extra]
        rc, _, err, peak = clitest.run_measured(self.peak_rss, args, self.work)
        return rc, err, peak, self._json(rc)

    def ranks(self, n, nz, out, size=SIZE):
        args = [self.mpirun, "--oversubscribe", "-n", str(n), self.mpi, "extract",
                *self.source(nz), "--iso", ISO, "-o", out, "-q", "--json", "j.json",
                "--max-memory", size]
        rc, _, err, peak = clitest.run_measured(self.peak_rss, args, self.work, env=ENV,
                                                timeout=900)
        return rc, err, peak, self._json(rc)

    def path(self, name):
        return os.path.join(self.work, name)

    def remove(self, *names):
        for f in names:
            if os.path.exists(self.path(f)):
                os.unlink(self.path(f))


def make_volume(work):
    with open(os.path.join(work, "v.raw"), "wb") as f:
        for k in range(NZ):
            f.write(clitest.busy_slice(k, NX, NY).tobytes())
    with open(os.path.join(work, "v.raw"), "rb") as f:
        head = f.read(64 * NX * NY * 2)
    for n in (64, 2):
        with open(os.path.join(work, f"v{n}.raw"), "wb") as g:
            g.write(head[:n * NX * NY * 2])


def check_ranks(r, limit, fmt, ns):
    ref = f"ref.{fmt}"
    rc, err, peak1, js1 = r.single(NZ, ref)
    if rc:
        fail(f"isomend extract {fmt}", err.strip())
        return
    if not js1["streamed"]:
        fail(f"isomend extract {fmt}", "not streamed")
    print(f"     {fmt}: {js1['triangles']} triangles; isomend extract --max-memory {SIZE} "
          f"streamed, peak {peak1 / MIB:.1f} MiB")
    for n in ns:
        rc, err, overhead, _ = r.ranks(n, 2, "tiny." + fmt)
        if rc:
            fail(f"{n} ranks {fmt}, overhead", err.strip())
            continue
        out = f"m{n}.{fmt}"
        rc, err, peak, js = r.ranks(n, NZ, out)
        if rc:
            fail(f"{n} ranks {fmt}", err.strip())
            continue
        label = (f"{n} rank{'s' if n > 1 else ''} {fmt}: peak {peak / MIB:.1f} MiB measured, "
                 f"{js['peak_memory'] / MIB:.1f} MiB reported, within --max-memory {SIZE} + "
                 f"overhead {overhead / MIB:.1f} MiB (2 slices)")
        if peak > limit + overhead:
            fail(label, "the measured peak is beyond the limit plus the overhead")
        if js["peak_memory"] > limit + overhead:
            fail(label, "the reported peak is beyond the limit plus the overhead")
        if js["vertices"] != js1["vertices"] or js["triangles"] != js1["triangles"]:
            fail(label, f"{js['vertices']} / {js['triangles']} vertices / triangles, "
                 f"{js1['vertices']} / {js1['triangles']} expected")
        if not clitest.same_file(r.path(ref), r.path(out)):
            fail(label, "the file differs from isomend extract's")
        r.remove(out)
        if n == ns[-1]:  # a rank's memory does not grow with its slab
            rc, err, peak64, _ = r.ranks(n, 64, "s64." + fmt)
            if rc:
                fail(f"{label}; 64 slices", err.strip())
            elif abs(peak - peak64) > 4 * MIB:
                fail(label, f"peak {peak / MIB:.1f} MiB at {NZ} slices, {peak64 / MIB:.1f} MiB "
                     "at 64")
            else:
                label += f"; 64 slices {peak64 / MIB:.1f} MiB"
            r.remove("s64." + fmt)
        r.remove("tiny." + fmt)
        if not clitest.failed(label):
            print(f"ok   {label}")
    r.remove(ref)


def check_in_memory(r, limit):
    """The volume needs several times the limit in memory: the test proves something."""
    rc, err, peak, js = r.single(NZ, "mem.ply", size="64G", extra=["--in-memory"])
    r.remove("mem.ply")
    label = (f"in memory, isomend extract peaks at {peak / MIB:.0f} MiB "
             f"({peak / limit:.1f}x --max-memory {SIZE})")
    if rc or js["streamed"]:
        fail("in memory", err.strip() or "streamed")
    elif peak < 4 * limit:
        fail(label, "not 4x the limit: the test proves nothing")
    else:
        print(f"ok   {label}")


def check_refusal(r):
    rc, err, _, _ = r.ranks(2, NZ, "refused.ply", size="16M")
    if rc != 2 or "--max-memory 16" not in err or os.path.exists(r.path("refused.ply")):
        fail("a limit below a rank's need", f"exit {rc}: {err.strip()}")
    else:
        line = [x for x in err.splitlines() if "--max-memory" in x][0]
        print(f"ok   --max-memory 16M is refused: {line}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--isomend-mpi", required=True)
    ap.add_argument("--mpirun", required=True)
    ap.add_argument("--peak-rss", required=True, help="tests/common/peak_rss.c, built")
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    r = Runs(a)
    make_volume(a.work)
    limit = int(SIZE[:-1]) * MIB
    check_in_memory(r, limit)
    check_ranks(r, limit, "ply", (1, 2, 3))
    check_ranks(r, limit, "stl", (2,))
    check_refusal(r)
    shutil.rmtree(a.work, ignore_errors=True)
    return clitest.summary()


if __name__ == "__main__":
    sys.exit(main())
