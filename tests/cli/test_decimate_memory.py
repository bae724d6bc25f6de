#!/usr/bin/env python3
"""The streamed decimation's and smoothing's memory: what they hold at their
largest within what the memory plan counts for them, and a run under
--max-memory within the limit.

Regression: the plan counted isomend_decimate_stream_memory() for the chunk
height it chose, and that estimate was low for chunks of 2 layers and more (a
192 x 192 x 3641 stack at --max-memory 32M peaked at 48 MiB when the plan
gave the decimation chunks of 2 layers: the window's slots, the measurement's
triangles and the padded cap's window were not counted).  The core now counts
what the streams allocate (isomend_decimate_stream_peak_bytes(),
isomend_smooth_stream_peak_bytes()); the CLI reports it in --json as
`decimate_memory` and `smooth_memory` ({peak, planned}, as `check_memory`).

A gyroid-like u16 field (period 64, half the frequency along z, meshed at
1000.5: about 0.15 triangles a marched sample, the estimate's surface being
0.25), 128 x 128 x 160:

- --stream --decimate 0.1 with --chunk-layers 1, 2, 4, 8 and 16 (2 and 8
  forced as the plan might choose them), padded and not; --max-error alone
  and with --decimate 0.25 (chunks of 2 and 8); --smooth 4 with chunks of 2
  and 8 (with --decimate 0.1 too): each step's `peak` within its `planned`,
  and above zero (it was counted);
- the same meshes with --threads 1 and 2 (the accounting changes nothing);
- 128 x 128 x 2048 (64 MiB) under --max-memory 32M --decimate 0.1 --pad:
  streamed, decimated in chunks the plan chose, `decimate_memory.peak`
  within `planned`, and the process's peak resident memory (wait4 through
  tests/common/peak_rss.c) within 32 MiB plus the program's fixed overhead,
  its peak on the first two slices under the same limit (docs/streaming.md).

usage: test_decimate_memory.py --isomend PATH --peak-rss PATH --work DIR [--no-memory-bounds]
"""
import argparse
import json
import os
import shutil
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
import clitest  # noqa: E402
from clitest import fail  # noqa: E402

MIB = 1024 * 1024
NX = 128


def gyroid(path, nx, nz, period=64):
    """1000 + 600 g, g the gyroid at half the frequency along z (no sample on 1000.5)."""
    w = np.float32(2 * np.pi / period)
    x = (np.arange(nx, dtype=np.float32)[None, :] + np.float32(0.5)) * w
    y = (np.arange(nx, dtype=np.float32)[:, None] + np.float32(0.5)) * w
    sxcy, sy, cx = np.sin(x) * np.cos(y), np.sin(y), np.cos(x)
    with open(path, "wb") as f:
        for k in range(nz):
            z = np.float32((k + 0.5) * 0.5) * w
            f.write((1000 + 600 * (sxcy + sy * np.cos(z) + np.sin(z) * cx)).astype("<u2").tobytes())


def extract(exe, work, src, flags, out, peak_rss=None):
    args = [exe, "extract", *src, "-q", "-o", out, "--json", "j.json", *flags]
    if peak_rss:
        rc, _, err, peak = clitest.run_measured(peak_rss, args, work, timeout=900)
    else:
        (rc, _, err), peak = run_plain(args, work), 0
    j = None
    if rc == 0:
        with open(os.path.join(work, "j.json")) as f:
            j = json.load(f)
    return rc, err, peak, j


def run_plain(args, cwd):
    import subprocess
    p = subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=900)
    return p.returncode, p.stdout, p.stderr


def within(label, j, key):
    """j[key] = {peak, planned}: counted, and within the plan."""
    m = j.get(key)
    if not m or not m.get("peak") or not m.get("planned"):
        fail(label, f"{key}: {m}")
        return ""
    if m["peak"] > m["planned"]:
        fail(label, f"{key}: peak {m['peak'] / MIB:.2f} MiB beyond the planned "
                    f"{m['planned'] / MIB:.2f} MiB")
    return f"{key[:-7]} {m['peak'] / MIB:.1f} of {m['planned'] / MIB:.1f} MiB"


def test_chunks(exe, work):
    nz = 160
    gyroid(os.path.join(work, "g.raw"), NX, nz)
    base = ["g.raw", "--raw", f"{NX},{NX},{nz}:u16", "--iso", "1000.5", "--stream"]
    cases = []
    for pad in (["--pad"], []):
        for k in (1, 2, 4, 8, 16):
            cases.append(pad + ["--decimate", "0.1", "--chunk-layers", str(k)])
    for k in (2, 8):
        cases.append(["--pad", "--max-error", "0.3", "--chunk-layers", str(k)])
        cases.append(["--pad", "--decimate", "0.25", "--max-error", "0.3", "--chunk-layers", str(k)])
        cases.append(["--pad", "--smooth", "4", "--chunk-layers", str(k)])
        cases.append(["--pad", "--smooth", "4", "--decimate", "0.1", "--chunk-layers", str(k)])
    for flags in cases:
        label = " ".join(flags)
        rc, err, _, j = extract(exe, work, base, flags + ["--threads", "1"], "a.ply")
        if rc:
            fail(label, f"exit {rc}: {err.strip()}")
            continue
        d = j["postprocess"]
        said = []
        if "--smooth" in flags:
            said.append(within(label, j, "smooth_memory"))
        elif j.get("smooth_memory") is not None:
            fail(label, f"smooth_memory {j['smooth_memory']} without --smooth")
        if "--decimate" in flags or "--max-error" in flags:
            said.append(within(label, j, "decimate_memory"))
            if not d["decimate"] or d["decimate"]["chunk_layers"] != int(flags[-1]):
                fail(label, f"not decimated in chunks of {flags[-1]}: {d['decimate']}")
        # the same mesh on 2 threads: the accounting changes nothing
        rc, err, _, j2 = extract(exe, work, base, flags + ["--threads", "2"], "b.ply")
        if rc or not clitest.same_file(os.path.join(work, "a.ply"), os.path.join(work, "b.ply")):
            fail(label, f"--threads 2: exit {rc}, or not the bytes of --threads 1 {err.strip()}")
        if not clitest.failed(label):
            print(f"ok   {label}: {j['triangles']} triangles; {'; '.join(said)}", flush=True)
    for f in ("g.raw", "a.ply", "b.ply"):
        os.remove(os.path.join(work, f))


def test_limit(exe, peak_rss, work, bounds, size_mib=32, nz=2048):
    gyroid(os.path.join(work, "big.raw"), NX, nz)
    with open(os.path.join(work, "big.raw"), "rb") as f, open(os.path.join(work, "two.raw"), "wb") as g:
        g.write(f.read(2 * NX * NX * 2))
    size, limit = f"{size_mib}M", size_mib * MIB
    src = ["big.raw", "--raw", f"{NX},{NX},{nz}:u16", "--iso", "1000.5", "--pad"]
    two = ["two.raw", "--raw", f"{NX},{NX},2:u16", "--iso", "1000.5", "--pad"]
    # the fixed overhead: the same program on two slices under the same limit
    rc, err, overhead, _ = extract(exe, work, two, ["--max-memory", size], "t.ply", peak_rss)
    if rc:
        fail("overhead (2 slices)", err.strip())
        return
    rc, err, peak, j = extract(exe, work, src, ["--max-memory", size, "--decimate", "0.1"],
                               "big.ply", peak_rss)
    label = f"{NX}x{NX}x{nz} u16 --max-memory {size} --decimate 0.1 --pad"
    if rc:
        fail(label, f"exit {rc}: {err.strip()}")
        return
    d = j["postprocess"]["decimate"]
    label += (f": chunks of {d and d['chunk_layers']} layers, peak {peak / MIB:.1f} MiB "
              f"(limit + overhead {overhead / MIB:.1f} MiB), streaming bound "
              f"{j['memory_streaming'] / MIB:.1f} MiB, check {'on' if j['check'] else 'off'}; "
              + within(label, j, "decimate_memory"))
    if not j["streamed"] or not d or not d["streamed"]:
        fail(label, "not streamed and decimated")
    if j["memory_streaming"] > limit:
        fail(label, "the plan's streaming bound beyond the limit")
    if bounds and peak > limit + overhead:
        fail(label, "the peak is beyond --max-memory plus the fixed overhead")
    for f in ("big.raw", "two.raw", "big.ply", "t.ply"):
        if os.path.exists(os.path.join(work, f)):
            os.remove(os.path.join(work, f))
    if not clitest.failed(label):
        print(f"ok   {label}", flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--isomend", required=True)
    ap.add_argument("--peak-rss", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--no-memory-bounds", action="store_true",
                    help="do not assert resident peaks (the sanitizers' shadow memory counts)")
    a = ap.parse_args()
    exe = os.path.abspath(a.isomend)
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    test_chunks(exe, a.work)
    test_limit(exe, os.path.abspath(a.peak_rss), a.work, not a.no_memory_bounds)
    shutil.rmtree(a.work, ignore_errors=True)
    return clitest.summary()


if __name__ == "__main__":
    sys.exit(main())
