#!/usr/bin/python3
"""bench.py's plan and volumes, without running an extractor.

- The volumes generated in slabs on every core equal, to the bit, the same
  definitions computed on the whole array in one thread (the way bench.py
  generated them before; a changed array would change every published figure
  without FIELD_VERSION saying so).
- Quick mode's plan (volume_jobs): Flying Edges in 2 rounds where isomend has
  3 (or --repeats, if fewer), measured at every thread count; the extractors
  measured once, once.

Usage: test_plan.py BENCH_PY
"""
import argparse
import importlib.util
import sys

import numpy as np


def load(path):
    spec = importlib.util.spec_from_file_location("bench", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def reference_field(b, name, n):
    """The fields on the whole array, one operation after another."""
    if name == "sphere":
        c = np.arange(n, dtype=np.float32) - np.float32((n - 1) / 2)
        r2 = c[:, None, None] ** 2 + c[None, :, None] ** 2
        r2 = r2 + c[None, None, :] ** 2
        return (np.float32(0.4 * n) - np.sqrt(r2)).astype(np.float32)
    if name == "noise":
        import scipy.ndimage as nd
        w = np.random.default_rng(1).standard_normal((n, n, n), dtype=np.float32)
        f = nd.gaussian_filter(w, b.NOISE_SIGMA_AT_256 * n / 256.0, output=np.float32,
                               mode="wrap")
        f /= np.float32(f.std(dtype=np.float64))
        return f
    return b.make_float_field(name, n)  # the gyroid is not split


def reference_u8(b, name, f):
    u = f * np.float32(b.U8_SCALE[name])
    u += np.float32(127.5)
    np.clip(u, 0, 255, out=u)
    return np.rint(u).astype(np.uint8)


def main():
    b = load(sys.argv[1])
    failures = 0
    for name in ("sphere", "gyroid", "noise"):
        for n in (5, 33, 64):
            f = b.make_float_field(name, n)
            ref = reference_field(b, name, n)
            same_f = f.dtype == ref.dtype and np.array_equal(f.view(np.uint32),
                                                             ref.view(np.uint32))
            same_u = np.array_equal(b.to_u8(name, f), reference_u8(b, name, ref))
            if not (same_f and same_u):
                print("FAIL %s %d: float32 identical %s, uint8 identical %s"
                      % (name, n, same_f, same_u))
                failures += 1

    threads = [1, 2]
    for repeats in (1, 2, 3, 5):
        args = argparse.Namespace(quick=True, repeats=repeats, calls=2)

        def jobs(field, size, dtype, t, peers=("isomend", "fe", "isomend-geom")):
            return {e: (r, c) for e, r, c in
                    b.volume_jobs(args, peers, field, size, dtype, t, threads, repeats)}

        for field, size in (("sphere", 256), ("gyroid", 256), ("sphere", 512)):
            for t in threads:
                got = jobs(field, size, "f32", t)
                want = {"isomend": (repeats, 2), "fe": (min(repeats, 2), 1)}
                if size == 256 and t == 1:
                    want["isomend-geom"] = (1, 2)  # once, at one thread
                if got != want:
                    print("FAIL quick plan, --repeats %d, %s %d at %d threads: %s, expected %s"
                          % (repeats, field, size, t, got, want))
                    failures += 1
        got = [jobs("noise", 512, "u8", t) for t in threads]
        if got != [{}, {"isomend": (1, 2)}]:  # the memory goal's volume: once, all threads
            print("FAIL quick plan, --repeats %d, noise 512 u8: %s" % (repeats, got))
            failures += 1
    print("bench plan: %s" % ("ok" if not failures else "%d failures" % failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
