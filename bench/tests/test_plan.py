#!/usr/bin/python3
"""bench.py's plan and volumes, without running an extractor.

- The volumes generated in slabs on every core equal, to the bit, the same
  definitions computed on the whole array in one thread (the way bench.py
  generated them before; a changed array would change every published figure
  without FIELD_VERSION saying so).
- Quick mode's plan (volume_jobs): on the goal volumes isomend warm in 3 rounds
  (or --repeats, if fewer) and cold in 1, Flying Edges warm in 2 rounds of 2
  calls and cold in 1 of 1, at every thread count; the extractors measured
  once, once, warm.
- The memory regimes (check_regimes): every measured extractor is measured warm,
  in full mode cold too; a child started warm keeps freed memory and a cold one
  does not; the results file's headline is the warm ratio, the cold one is
  labelled cold, and --check refuses a warm row whose allocator did not keep.

Usage: test_plan.py BENCH_PY
"""
import argparse
import importlib.util
import subprocess
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


def check_regimes(b, threads):
    """The two memory regimes: every measured extractor is measured warm (the
    headline) in every mode; full mode also cold; a warm child's allocator keeps
    freed memory and a cold one's does not; the results file labels them so."""
    failures = 0
    vols = [(f, n, d) for f in ("sphere", "gyroid", "noise") for n in (24, 128, 256, 512)
            for d in ("f32", "u8")]
    for quick in (True, False):
        args = argparse.Namespace(quick=quick, repeats=3, calls=2)
        for f, n, d in vols:
            for t in threads:
                js = b.volume_jobs(args, b.ALL_PEERS, f, n, d, t, threads, 3)
                measured = {e for e, _g, _r, _c in js}
                warm = {e for e, g, _r, _c in js if g == "warm"}
                cold = {e for e, g, _r, _c in js if g == "cold"}
                bad = [g for _e, g, _r, _c in js if g not in b.REGIMES]
                if measured != warm or bad or (not quick and cold != measured):
                    print("FAIL regimes (%s mode) %s %d %s at %d threads: measured %s, warm "
                          "%s, cold %s, unknown %s" % ("quick" if quick else "full", f, n, d, t,
                                                       sorted(measured), sorted(warm),
                                                       sorted(cold), bad))
                    failures += 1

    # The children's environments: the tunables in warm, none of glibc.malloc's in cold,
    # the other tunables kept; the child is told its regime.
    env = {"GLIBC_TUNABLES": "glibc.malloc.mmap_max=7:glibc.cpu.x86_rep_movsb_threshold=2048",
           "PATH": "/usr/bin:/bin"}
    warm = b.regime_env("warm", env)["GLIBC_TUNABLES"].split(":")
    cold = b.regime_env("cold", env).get("GLIBC_TUNABLES", "").split(":")
    only_malloc = {"GLIBC_TUNABLES": "glibc.malloc.tcache_count=0"}
    if sorted(warm) != sorted(["glibc.cpu.x86_rep_movsb_threshold=2048"] +
                              list(b.WARM_TUNABLES)) or \
            cold != ["glibc.cpu.x86_rep_movsb_threshold=2048"] or \
            "GLIBC_TUNABLES" in b.regime_env("cold", only_malloc):
        print("FAIL regime_env: warm %s, cold %s" % (warm, cold))
        failures += 1
    for regime in b.REGIMES:
        a = argparse.Namespace(lib_dir=None, floor_lib=None)
        cmd, cenv = b.child_command(a, "fe", "/v.npy", 0.0, 1, 2, regime)
        if cmd[cmd.index("--child-regime") + 1] != regime or \
                cenv.get("GLIBC_TUNABLES") != b.regime_env(regime).get("GLIBC_TUNABLES"):
            print("FAIL child_command %s: %s, GLIBC_TUNABLES=%s" % (regime, cmd,
                                                                    cenv.get("GLIBC_TUNABLES")))
            failures += 1
        # A process started in that environment: does its malloc keep freed memory?
        code = ("import importlib.util, sys; s = importlib.util.spec_from_file_location("
                "'bench', sys.argv[1]); m = importlib.util.module_from_spec(s); "
                "s.loader.exec_module(m); print(m.allocator_keeps_freed_memory())")
        out = subprocess.run([sys.executable, "-c", code, b.__file__], env=cenv,
                             stdout=subprocess.PIPE, text=True).stdout.strip()
        if out != str(regime == "warm"):
            print("FAIL %s child: allocator keeps freed memory: %s" % (regime, out))
            failures += 1

    # The results file and --check: the headline is warm, cold is labelled cold.
    def row(ext, regime, t, ms, faults, keeps=None):
        return {"field": "sphere", "size": 256, "dtype": "f32", "extractor": ext,
                "label": b.EXTRACTORS[ext][0], "regime": regime, "threads": t, "iso": 0.0,
                "parallel": True, "repeats": 3, "calls": 2, "times": [ms / 1e3],
                "cpu_times": [ms / 1e3], "sys_times": [0.0], "minflt": [faults],
                "reported_kib": [0], "median": ms / 1e3, "min": ms / 1e3, "cpu": ms / 1e3,
                "sys": 0.0, "user": ms / 1e3, "faults": faults, "floor": 2e-3, "first": ms / 1e3,
                "first_faults": faults, "floor_times": [2e-3], "numpy_sum_times": [3e-3],
                "floor_impl": "C", "floor_sum": 1.0, "numpy_sum": 1.0, "input_bytes": 64 << 20,
                "output_bytes": 9 << 20, "peak_extra_kb": 1024, "triangles": 395132,
                "vertices": 197568, "allocator_keeps": regime == "warm" if keeps is None
                else keeps, "extra": {}}
    results = [row("isomend", "warm", 1, 13.0, 7), row("isomend", "cold", 1, 14.0, 10),
               row("fe", "warm", 1, 39.0, 0), row("fe", "cold", 1, 140.0, 8482)]
    info = {"mode": "quick", "command": "bench/bench.py --quick", "started": "now",
            "seconds": 1.0, "repeats": 3, "calls": 2, "page_cost": [1.7, 0.07, 3.7]}
    text = b.render(info, results, [1])
    line = next((x for x in text.splitlines() if x.startswith("| sphere 256³ f32 | 1 |")), "")
    cells = [c.strip() for c in line.split("|")[1:-1]]
    detail = [x for x in text.splitlines() if x.startswith("| vtkFlyingEdges3D geometry")]
    if len(cells) < 14 or cells[2:5] != ["13.0", "39.0", "3.00 ✔"] or \
            cells[11:14] != ["14.0 / 140", "10.00", "10 / 8482"] or \
            len(detail) != 2 or "(cold)" in detail[0] or "(cold)" not in detail[1] or \
            "8482 faults per cold call" not in text:
        print("FAIL render: goal row %s, detail rows %s" % (cells, detail))
        failures += 1
    if b.check(results, ["isomend", "fe"]):
        print("FAIL check on consistent results: %s" % b.check(results, ["isomend", "fe"]))
        failures += 1
    results[2] = row("fe", "warm", 1, 39.0, 0, keeps=False)  # a cold child labelled warm
    if not any("measured as warm" in p for p in b.check(results, ["isomend", "fe"])):
        print("FAIL check: a warm row whose allocator did not keep freed memory passed")
        failures += 1
    return failures


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
            return {(e, g): (r, c) for e, g, r, c in
                    b.volume_jobs(args, peers, field, size, dtype, t, threads, repeats)}

        for field, size in (("sphere", 256), ("gyroid", 256), ("noise", 256), ("sphere", 512)):
            for t in threads:
                got = jobs(field, size, "f32", t)
                want = {("isomend", "warm"): (repeats, 2), ("isomend", "cold"): (1, 2),
                        ("fe", "warm"): (min(repeats, 2), 2), ("fe", "cold"): (1, 1)}
                if size == 256 and t == 1:
                    want[("isomend-geom", "warm")] = (1, 2)  # once, at one thread
                if got != want:
                    print("FAIL quick plan, --repeats %d, %s %d at %d threads: %s, expected %s"
                          % (repeats, field, size, t, got, want))
                    failures += 1
        got = [jobs("noise", 512, "u8", t) for t in threads]
        if got != [{}, {("isomend", "warm"): (1, 2)}]:  # the memory goal: once, all threads
            print("FAIL quick plan, --repeats %d, noise 512 u8: %s" % (repeats, got))
            failures += 1
    failures += check_regimes(b, threads)
    print("bench plan: %s" % ("ok" if not failures else "%d failures" % failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
