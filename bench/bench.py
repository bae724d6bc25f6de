#!/usr/bin/python3
"""isomend against its peers, on the same arrays, in one run.

What is timed (the library call only: no file I/O, volumes already in memory)

  isomend DMC+normals   isomend_extract(), method DMC, vertex normals, one shared
                        vertex per intersected edge, hole-free (the spec's goal row)
  isomend DMC geometry  the same without normals (ISOMEND_FLAG_NO_NORMALS)
  isomend ... recycling the first row's call through isomend_extract_recycle(), handed the
                        previous call's mesh (a program extracting one surface after
                        another); its first call has none, so only its timed calls recycle
  FE geometry / FE+n    vtkFlyingEdges3D, normals (and gradients, scalars) off / normals on
  vtkMarchingCubes      geometry only (normals, gradients, scalars off); single-threaded
  skimage lewiner       skimage.measure.marching_cubes(method='lewiner'); always computes
                        normals; single-threaded
  OpenVDB               FloatGrid.copyFromArray() + convertToPolygons(adaptivity=0), i.e.
                        openvdb::tools::volumeToMesh; the dense-to-VDB copy is included
                        because every other extractor starts from the same dense array
  floor                 the memory-read floor: the sum of every voxel by a small C loop
                        (bench/floor.c, built by CMake), measured in every child process
                        right before its extractor, on the same array

How it is measured

  Every round runs in a fresh child process pinned to N cores (sched_setaffinity:
  TBB, used by VTK and OpenVDB, and isomend then see N cores; VTK also gets
  vtkSMPTools.Initialize(N), isomend options.threads = N).  The child loads the volume
  from a .npy file, warms the extractor up on a 16^3 subsample of it (thread pools, lazy
  binding), measures the floor, then makes 1 + C full-size calls (C = --calls, 3 by
  default; quick mode's plan is quick_policy's), resetting its peak-RSS mark
  (/proc/self/clear_refs = 5) before each: the first is reported apart ("first call"),
  the other C are the measurement: wall time, CPU time (and its system part), minor page
  faults (ru_minflt) and the peak RSS above what it held before the call (the "extra"
  memory: output, temporaries).

  Two memory regimes (see REGIMES below), every extractor alike: *warm*, the headline
  and what the goals are judged on, a child whose allocator keeps the memory a call
  frees, so that the timed calls, back to back after the first, reuse it as a program
  extracting many surfaces does; *cold*, glibc's default allocator, which hands large
  freed arrays back to the kernel, so that every call faults its arrays in again (on a
  virtual machine whose every 4 KiB fault traps to the host, a large part of a peer's
  call: its large arrays are on small pages).  The first call of a process pays for
  fresh memory in either regime; on a
  virtual machine that returns freed memory to its host (virtio-balloon free page
  reporting, as on the machine of docs/bench-results.md) that cost depends on what the
  previous process did.  Where the kernel has the page_reporting module, the run
  records how much free memory it handed back to the host (reported_kib) over the run
  and, in the JSON, from the end of each call to the end of the next.  The runs are made
  in rounds -- every extractor in each of its regimes once, then again -- so that the
  extractors and regimes compared take turns on a shared machine.  Times are medians
  over all timed calls of all rounds.

Modes: --smoke (seconds, for ctest), --quick (under two minutes: the goal volumes),
default full (every field, size, type, thread count, and the Colin27 MRI).
Run with Debian's /usr/bin/python3 (numpy, vtk, skimage, pyopenvdb, nibabel).
"""
import argparse
import ctypes
import datetime
import gc
import json
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
FIELD_VERSION = 1  # bump when a field's definition changes (invalidates the cache)

# ---------------------------------------------------------------------------- fields

FIELDS = ("sphere", "gyroid", "noise", "colin27")
# Scale that maps a float field onto uint8 around 127.5 (iso 127.5, so no sample
# equals the level), and the float iso level.
U8_SCALE = {"sphere": 16.0, "gyroid": 80.0, "noise": 40.0}
GYROID_PERIODS = 16       # periods across the box, at every size
NOISE_SIGMA_AT_256 = 1.5  # Gaussian smoothing of white noise, in voxels at 256^3
COLIN_ISO = 60.0          # ch2better (uint8, 0..130): skin/skull boundary
ONCE = "once"             # quick_policy: one round, at one thread (isomend: all threads)


def field_description(name):
    return {
        "sphere": "R - |p - c|, R = 0.4 N (a ball of radius 0.4 N), iso 0",
        "gyroid": "sin x cos y + sin y cos z + sin z cos x, %d periods across the box, iso 0"
                  % GYROID_PERIODS,
        "noise": "white Gaussian noise (seed 1) smoothed by a Gaussian of sigma %.1f N/256 "
                 "voxels, normalised to unit variance, iso 0" % NOISE_SIGMA_AT_256,
        "colin27": "Colin27 MRI, ch2better.nii.gz from Debian's mricron-data "
                   "(301x370x316, uint8, 0.5 mm), iso %g" % COLIN_ISO,
    }[name]


def _slabs(n, fn):
    """fn(lo, hi) over slabs of rows 0..n of the first array axis, in as many threads as
    there are cores: numpy's element-wise operations and scipy.ndimage's filters release
    the GIL, and each slab does exactly the operations the whole array would, so the
    result is the same to the bit (quick mode's volumes are generated on first use, and
    generating them one thread at a time took 17-24 s of a fresh machine's run)."""
    from concurrent.futures import ThreadPoolExecutor
    k = max(1, min(os.cpu_count() or 1, 8))
    cuts = [n * i // k for i in range(k + 1)]
    with ThreadPoolExecutor(k) as ex:
        for f in [ex.submit(fn, lo, hi) for lo, hi in zip(cuts, cuts[1:]) if hi > lo]:
            f.result()


def make_float_field(name, n):
    import numpy as np
    if name == "sphere":
        c = np.arange(n, dtype=np.float32) - np.float32((n - 1) / 2)
        r2 = c[:, None, None] ** 2 + c[None, :, None] ** 2
        cx2 = c[None, None, :] ** 2
        out = np.empty((n, n, n), dtype=np.float32)

        def slab(lo, hi):  # R - sqrt((z^2 + y^2) + x^2), in float32
            s = out[lo:hi]
            np.add(r2[lo:hi], cx2, out=s)
            np.sqrt(s, out=s)
            np.subtract(np.float32(0.4 * n), s, out=s)
        _slabs(n, slab)
        return out
    if name == "gyroid":
        x = (np.arange(n, dtype=np.float64) + 0.5) * (2 * np.pi * GYROID_PERIODS / n)
        s, c = np.sin(x).astype(np.float32), np.cos(x).astype(np.float32)
        # array axes (z, y, x): f = sin x cos y + sin y cos z + sin z cos x
        f = s[None, None, :] * c[None, :, None]
        f = f + s[None, :, None] * c[:, None, None]
        f += s[:, None, None] * c[None, None, :]
        return f.astype(np.float32, copy=False)
    if name == "noise":
        import scipy.ndimage as nd
        rng = np.random.default_rng(1)
        w = rng.standard_normal((n, n, n), dtype=np.float32)
        # scipy's gaussian_filter, axis after axis in float32 with periodic ends, each
        # axis's pass split across the others (a line's result does not depend on them).
        sigma = NOISE_SIGMA_AT_256 * n / 256.0
        f = np.empty_like(w)
        _slabs(n, lambda lo, hi: nd.gaussian_filter1d(
            w[:, lo:hi], sigma, axis=0, output=f[:, lo:hi], mode="wrap"))
        del w
        for axis in (1, 2):
            _slabs(n, lambda lo, hi, a=axis: nd.gaussian_filter1d(
                f[lo:hi], sigma, axis=a, output=f[lo:hi], mode="wrap"))
        f /= np.float32(f.std(dtype=np.float64))
        return f
    raise ValueError("unknown field %r" % name)


def to_u8(name, f):
    import numpy as np
    u = np.empty(f.shape, dtype=np.uint8)

    def slab(lo, hi):  # rint(clip(f * scale + 127.5, 0, 255)), in float32
        t = f[lo:hi] * np.float32(U8_SCALE[name])
        t += np.float32(127.5)
        np.clip(t, 0, 255, out=t)
        np.rint(t, out=t)
        u[lo:hi] = t
    _slabs(f.shape[0], slab)
    return u


def colin27_path(cache):
    """ch2better.nii.gz: installed mricron-data, else `apt-get download` into the cache."""
    for p in ("/usr/share/mricron/templates/ch2better.nii.gz",
              os.path.join(cache, "mricron", "usr/share/mricron/templates/ch2better.nii.gz")):
        if os.path.exists(p):
            return p
    dl = os.path.join(cache, "mricron-download")
    os.makedirs(dl, exist_ok=True)
    try:
        subprocess.run(["apt-get", "download", "mricron-data"], cwd=dl, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        debs = [f for f in os.listdir(dl) if f.endswith(".deb")]
        if not debs:
            raise RuntimeError("apt-get download mricron-data produced no .deb")
        subprocess.run(["dpkg-deb", "-x", os.path.join(dl, debs[0]),
                        os.path.join(cache, "mricron")], check=True)
    except (OSError, subprocess.CalledProcessError, RuntimeError) as e:
        raise RuntimeError("Colin27 MRI unavailable (install mricron-data or allow "
                           "`apt-get download mricron-data`): %s" % e)
    p = os.path.join(cache, "mricron", "usr/share/mricron/templates/ch2better.nii.gz")
    if not os.path.exists(p):
        raise RuntimeError("mricron-data has no %s" % p)
    return p


def volume_file(cache, name, n, dtype):
    """Path of a cached .npy volume (generated on first use) and its iso level."""
    import numpy as np
    if name == "colin27":
        iso = COLIN_ISO
        path = os.path.join(cache, "v%d-colin27-%s.npy" % (FIELD_VERSION, dtype))
        if not os.path.exists(path):
            import nibabel
            img = nibabel.load(colin27_path(cache))
            a = np.asarray(img.dataobj)  # (x, y, z), x fastest in the file
            a = np.ascontiguousarray(a.transpose(2, 1, 0))  # our arrays are (z, y, x)
            _save(path, a.astype(np.float32) if dtype == "f32" else a.astype(np.uint8))
        return path, iso
    iso = 127.5 if dtype == "u8" else 0.0
    path = os.path.join(cache, "v%d-%s-%d-%s.npy" % (FIELD_VERSION, name, n, dtype))
    if not os.path.exists(path):
        f = make_float_field(name, n)
        _save(path, to_u8(name, f) if dtype == "u8" else f)
        del f
    return path, iso


def _save(path, a):
    import numpy as np
    d = os.path.dirname(path)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".npy", dir=d)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.save(fh, a)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


# ------------------------------------------------------------------ the extractors
# Each runs in a child process: setup(array, iso, threads) returns a callable that
# performs one extraction and returns (triangles, vertices, output bytes, extra).

class IsomendVolume(ctypes.Structure):
    _fields_ = [("data", ctypes.c_void_p), ("type", ctypes.c_int),
                ("dims", ctypes.c_int64 * 3), ("strides", ctypes.c_int64 * 3),
                ("spacing", ctypes.c_double * 3), ("origin", ctypes.c_double * 3),
                ("slice_origins", ctypes.c_void_p)]  # isomend.h: NULL, a uniform grid


class IsomendOptions(ctypes.Structure):
    _fields_ = [("iso", ctypes.c_double), ("method", ctypes.c_int), ("flags", ctypes.c_uint),
                ("threads", ctypes.c_int), ("progress", ctypes.c_void_p),
                ("progress_user", ctypes.c_void_p)]


class IsomendStats(ctypes.Structure):
    _fields_ = [("cubes", ctypes.c_uint64), ("case_histogram", ctypes.c_uint64 * 15),
                ("ambiguous_faces", ctypes.c_uint64), ("inverted_combinations", ctypes.c_uint64),
                ("triangles_by_origin", ctypes.c_uint64 * 3), ("nan_samples", ctypes.c_uint64),
                ("vertices", ctypes.c_uint64), ("triangles", ctypes.c_uint64)]


ISOMEND_TYPES = {"uint8": 0, "int8": 1, "uint16": 2, "int16": 3, "int32": 4, "float32": 5,
                 "float64": 6}
ISOMEND_FLAG_NO_NORMALS = 1


def load_isomend(lib_dir):
    """The core library through a minimal ctypes binding: the bench times
    isomend_extract() alone, as it times vtkAlgorithm::Update() alone."""
    names = ["libisomend.so", "libisomend.so.0"]
    d = lib_dir or os.environ.get("ISOMEND_LIB_DIR")
    tried = []
    for n in names:
        p = os.path.join(d, n) if d else n
        tried.append(p)
        try:
            lib = ctypes.CDLL(p)
            break
        except OSError:
            continue
    else:
        raise RuntimeError("libisomend not found (tried %s); pass --lib-dir or set "
                           "ISOMEND_LIB_DIR" % ", ".join(tried))
    P = ctypes.POINTER
    lib.isomend_volume_init.argtypes = [P(IsomendVolume), ctypes.c_void_p, ctypes.c_int,
                                        ctypes.c_int64, ctypes.c_int64, ctypes.c_int64]
    lib.isomend_volume_init.restype = None
    lib.isomend_options_init.argtypes = [P(IsomendOptions)]
    lib.isomend_options_init.restype = None
    lib.isomend_extract.argtypes = [P(IsomendVolume), P(IsomendOptions),
                                    P(ctypes.c_void_p), P(IsomendStats)]
    lib.isomend_extract.restype = ctypes.c_int
    lib.isomend_extract_recycle.argtypes = lib.isomend_extract.argtypes
    lib.isomend_extract_recycle.restype = ctypes.c_int
    lib.isomend_status_string.argtypes = [ctypes.c_int]
    lib.isomend_status_string.restype = ctypes.c_char_p
    lib.isomend_mesh_destroy.argtypes = [ctypes.c_void_p]
    lib.isomend_mesh_destroy.restype = None
    for f in ("isomend_mesh_vertex_count", "isomend_mesh_triangle_count"):
        getattr(lib, f).argtypes = [ctypes.c_void_p]
        getattr(lib, f).restype = ctypes.c_size_t
    lib.isomend_version.restype = ctypes.c_char_p
    return lib


def setup_isomend(a, iso, threads, args, normals, recycle=False):
    """isomend_extract(); with recycle, isomend_extract_recycle() handed the previous
    call's mesh (the first call of a process has none), as a program extracting one
    surface after another would call it."""
    lib = load_isomend(args.lib_dir)
    vol = IsomendVolume()
    nz, ny, nx = a.shape
    lib.isomend_volume_init(ctypes.byref(vol), a.ctypes.data, ISOMEND_TYPES[a.dtype.name],
                            nx, ny, nz)
    opts = IsomendOptions()
    lib.isomend_options_init(ctypes.byref(opts))
    opts.iso = iso
    opts.method = 2  # ISOMEND_METHOD_DMC
    opts.threads = threads
    if not normals:
        opts.flags |= ISOMEND_FLAG_NO_NORMALS

    kept = ctypes.c_void_p()  # recycle: the last call's mesh, handed to the next

    def run():
        mesh = kept if recycle else ctypes.c_void_p()
        st = IsomendStats()
        call = lib.isomend_extract_recycle if recycle else lib.isomend_extract
        s = call(ctypes.byref(vol), ctypes.byref(opts), ctypes.byref(mesh), ctypes.byref(st))
        if s != 0:
            raise RuntimeError("isomend_extract: %s" % lib.isomend_status_string(s).decode())
        return mesh, st

    def measure(out):
        mesh, st = out
        nv = lib.isomend_mesh_vertex_count(mesh)
        nt = lib.isomend_mesh_triangle_count(mesh)
        nbytes = nv * 12 * (2 if normals else 1) + nt * 12 + nt  # + 1 origin byte per triangle
        extra = {"mend_triangles": st.triangles_by_origin[2],
                 "inverted_combinations": st.inverted_combinations,
                 "version": lib.isomend_version().decode()}
        if not recycle:  # else kept (the same object as mesh) goes to the next call
            lib.isomend_mesh_destroy(mesh)
        return nt, nv, nbytes, extra
    return run, measure


def setup_wrapper(a, iso, threads, args):
    """isomend through the Python wrapper of the Blender add-on: the same call plus
    its argument checks and the numpy views of the mesh's arrays (no copy)."""
    if args.lib_dir:
        os.environ["ISOMEND_LIB_DIR"] = args.lib_dir
    sys.path.insert(0, os.path.join(ROOT, "blender_addon", "isomend_import"))
    import isomend  # noqa: E402 (the wrapper module)

    def run():
        return isomend.extract(a, iso, method="dmc", normals=True, threads=threads)

    def measure(out):
        arrays = [x for x in (out.positions, out.normals, out.triangles, out.origins)
                  if x is not None]
        return (out.triangle_count, out.vertex_count, sum(x.nbytes for x in arrays),
                {"mend_triangles": out.stats["mending_triangles"]})
    return run, measure


def _vtk_image(a):
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.util.numpy_support import numpy_to_vtk
    img = vtkImageData()
    nz, ny, nx = a.shape
    img.SetDimensions(nx, ny, nz)
    arr = numpy_to_vtk(a.reshape(-1), deep=False)
    img.GetPointData().SetScalars(arr)
    return img, arr


def setup_vtk(a, iso, threads, args, cls, normals):
    from vtkmodules.vtkCommonCore import vtkSMPTools
    import vtkmodules.vtkFiltersCore as fc
    vtkSMPTools.Initialize(threads)
    img, keep = _vtk_image(a)

    def run():
        f = getattr(fc, cls)()
        f.SetInputData(img)
        f.SetValue(0, iso)
        f.SetComputeNormals(1 if normals else 0)
        f.ComputeGradientsOff()
        f.ComputeScalarsOff()
        f.Update()
        return f

    def measure(f):
        out = f.GetOutput()
        res = (out.GetNumberOfPolys(), out.GetNumberOfPoints(),
               out.GetActualMemorySize() * 1024, {"keep": id(keep)})
        return res
    return run, measure


def setup_skimage(a, iso, threads, args):
    from skimage.measure import marching_cubes

    def run():
        return marching_cubes(a, level=iso, method="lewiner")

    def measure(out):
        verts, faces, normals, values = out
        return len(faces), len(verts), sum(x.nbytes for x in out), {}
    return run, measure


def setup_openvdb(a, iso, threads, args):
    import numpy as np
    import pyopenvdb as vdb

    def run():
        # background: a value on the outside (< iso) so inactive tiles stay outside
        g = vdb.FloatGrid(float(a.min()))
        g.copyFromArray(a if a.dtype == np.float32 else a.astype(np.float32))
        return g.convertToPolygons(isovalue=float(iso), adaptivity=0.0)

    def measure(out):
        pts, tris, quads = out
        return len(tris) + 2 * len(quads), len(pts), sum(x.nbytes for x in out), \
            {"quads": len(quads)}
    return run, measure


EXTRACTORS = {
    # name: (label, setup, parallel)
    "isomend": ("isomend DMC+normals", lambda a, i, t, g: setup_isomend(a, i, t, g, True), True),
    "isomend-geom": ("isomend DMC geometry",
                     lambda a, i, t, g: setup_isomend(a, i, t, g, False), True),
    "isomend-recycle": ("isomend DMC+normals, recycling",
                        lambda a, i, t, g: setup_isomend(a, i, t, g, True, True), True),
    "isomend-py": ("isomend via Python wrapper", setup_wrapper, True),
    "fe": ("vtkFlyingEdges3D geometry",
           lambda a, i, t, g: setup_vtk(a, i, t, g, "vtkFlyingEdges3D", False), True),
    "fe-normals": ("vtkFlyingEdges3D +normals",
                   lambda a, i, t, g: setup_vtk(a, i, t, g, "vtkFlyingEdges3D", True), True),
    "vtkmc": ("vtkMarchingCubes geometry",
              lambda a, i, t, g: setup_vtk(a, i, t, g, "vtkMarchingCubes", False), False),
    "skimage": ("skimage marching_cubes lewiner", setup_skimage, False),
    "openvdb": ("OpenVDB volumeToMesh (adapt. 0)", setup_openvdb, True),
}
ALL_PEERS = ["isomend", "isomend-geom", "isomend-recycle", "isomend-py", "fe", "fe-normals",
             "vtkmc", "skimage", "openvdb"]


# ------------------------------------------------------------------- child process

def _status_kb(key):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    return 0


# Free page reporting (virtio-balloon): the guest kernel hands free memory blocks
# back to the host, which must then supply them again on first touch, at several
# times the price of memory the guest still holds (see page_cost).  Its module
# counts what it reported; None where the kernel has no such module.
PAGE_REPORTING = "/sys/module/page_reporting/parameters"


def _page_reporting(name):
    try:
        with open(os.path.join(PAGE_REPORTING, name)) as f:
            return f.read().strip()
    except OSError:
        return None


def _reported_kib():
    v = _page_reporting("reported_kib")
    return int(v) if v and v.isdigit() else None


# ------------------------------------------------------------- memory regimes
# What a call costs depends on whether the memory it allocates is already the
# process's.  glibc's malloc hands large freed blocks straight back to the kernel
# (blocks above 32 MiB are mmapped and unmapped on free; below, the top of the heap
# is trimmed), so a program that calls Flying Edges again gets its arrays as fresh
# pages, one minor fault per 4 KiB, which the kernel must zero (and, on a virtual
# machine, often get from the host): 0.5-0.9 ms per MB on the Intel PVM guest of
# 2026-12-03, 2.9-3.8 on the AMD one of 2026-12-02, a few ms per call elsewhere.
# Whether a program pays it depends on its past: the first time glibc unmaps a freed
# block of up to 32 MiB, it raises its mapping threshold to that size and its trim
# threshold to twice it, and blocks that size stay in the heap from then on (one
# 16 MB numpy array freed before Flying Edges' calls makes them fault-free).  So
# the regime is set, not left to chance:
#
#   warm  (the headline) the child's allocator keeps freed memory:
#         GLIBC_TUNABLES=glibc.malloc.mmap_max=0:glibc.malloc.trim_threshold=16 GiB
#         in its environment, so the calls after the first full-size one reuse the
#         memory the one before freed, as a long-running program's do.
#   cold  the default allocator, in a child where nothing raises its thresholds
#         before the timed calls: memory handed back between calls (the measurement
#         before issue 27).
#
# Both apply to every extractor alike.  isomend maps its output and work arrays
# itself (2 MiB pages) and unmaps them when the mesh is destroyed: the tunables do
# not change that, which is its behaviour in any program.  Each call's minor page
# faults (getrusage ru_minflt) are recorded, so a reader sees what the regimes change.
REGIMES = ("warm", "cold")
WARM_TUNABLES = ("glibc.malloc.mmap_max=0", "glibc.malloc.trim_threshold=17179869184")


def regime_env(regime, env=None):
    """The environment of a child in a regime: the caller's, with GLIBC_TUNABLES'
    glibc.malloc.* entries replaced by WARM_TUNABLES (warm) or removed (cold)."""
    if regime not in REGIMES:
        raise ValueError("unknown memory regime %r" % regime)
    env = dict(os.environ if env is None else env)
    kept = [t for t in env.get("GLIBC_TUNABLES", "").split(":")
            if t and not t.startswith("glibc.malloc.")]
    if regime == "warm":
        kept += WARM_TUNABLES
    if kept:
        env["GLIBC_TUNABLES"] = ":".join(kept)
    else:
        env.pop("GLIBC_TUNABLES", None)
    return env


class _Mallinfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks",
        "fordblks", "keepcost")]


def allocator_keeps_freed_memory():
    """Whether this process's malloc keeps a large freed block (the warm regime):
    64 MiB are allocated and freed; True if they came from the heap rather than a
    mapping of their own and are still free in it afterwards; None without glibc's
    mallinfo2 (glibc < 2.33)."""
    libc = ctypes.CDLL(None)
    info = getattr(libc, "mallinfo2", None)
    if info is None:
        return None
    info.restype = _Mallinfo2
    libc.malloc.restype = ctypes.c_void_p
    libc.malloc.argtypes = [ctypes.c_size_t]
    libc.free.argtypes = [ctypes.c_void_p]
    size = 64 << 20
    before = info()
    p = libc.malloc(size)
    if not p:
        return None
    mapped = info().hblkhd - before.hblkhd >= size
    libc.free(p)
    return not mapped and info().fordblks >= size


def _reset_peak():
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def load_floor(path):
    if not path:
        return None
    lib = ctypes.CDLL(path)
    lib.isomend_bench_sum_f32.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
    lib.isomend_bench_sum_f32.restype = ctypes.c_double
    lib.isomend_bench_sum_u8.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
    lib.isomend_bench_sum_u8.restype = ctypes.c_double
    lib.isomend_bench_page_cost.argtypes = [ctypes.c_size_t, ctypes.POINTER(ctypes.c_double)]
    lib.isomend_bench_page_cost.restype = ctypes.c_int
    return lib


def page_cost(path, mb):
    """The kernel's price of fresh memory now (ms per MB): 2 MiB pages the first time,
    2 MiB pages reused, 4 KiB pages reused (floor.c, isomend_bench_page_cost)."""
    lib = load_floor(path)
    out = (ctypes.c_double * 3)()
    if not lib or lib.isomend_bench_page_cost(mb, out) != 0:
        return None
    return [round(x, 3) for x in out]


def floor_sum(lib, a, threads):
    """The memory-read floor: every voxel read once (C loop; numpy if not built)."""
    if lib is not None and a.dtype.name == "float32":
        return lib.isomend_bench_sum_f32(a.ctypes.data, a.size, threads)
    if lib is not None and a.dtype.name == "uint8":
        return lib.isomend_bench_sum_u8(a.ctypes.data, a.size, threads)
    return float(a.sum(dtype="float64"))


def child_main(args):
    threads = args.child_threads
    keeps = allocator_keeps_freed_memory()
    ncpu = os.cpu_count() or 1
    if threads <= ncpu:
        os.sched_setaffinity(0, set(sorted(os.sched_getaffinity(0))[:threads]))
    import numpy as np
    label, setup, _parallel = EXTRACTORS[args.child_extractor]
    floor_lib = load_floor(args.floor_lib)
    rss_before_input = _status_kb("VmRSS")
    a = np.load(args.child_volume)
    rss_input = _status_kb("VmRSS")
    run, measure = setup(a, args.child_iso, threads, args)
    # One untimed call on a 16^3 subsample of the volume first (it crosses the level
    # like the volume): thread pools (TBB), lazy symbol binding and first-call
    # allocations are not what is measured.  A failure here shows in the timed call.
    step = [max(1, d // 16) for d in a.shape]
    small = np.ascontiguousarray(a[::step[0], ::step[1], ::step[2]])
    try:
        warm_run, warm_measure = setup(small, args.child_iso, threads, args)
        warm_measure(warm_run())
        del warm_run, warm_measure
    except Exception:  # noqa: BLE001 (only a warm-up)
        pass

    # The floor, in this process, on this array, before the extractor.
    floor_times, numpy_times = [], []
    fsum = None
    for _ in range(max(3, args.repeats)):
        t0 = time.perf_counter()
        fsum = floor_sum(floor_lib, a, threads)
        floor_times.append(time.perf_counter() - t0)
    for _ in range(2):
        t0 = time.perf_counter()
        nsum = float(a.sum(dtype=np.float64))
        numpy_times.append(time.perf_counter() - t0)

    times, cpus, systems, peaks, reported, faults = [], [], [], [], [], []
    result = None
    first_times, first_cpus, first_faults = [], [], []
    # Memory the VM reported to its host from the end of the previous call (whose
    # output is freed after it) to the end of this one: what the call may have had
    # to get back from the host.
    rep_prev = _reported_kib()
    for r in range(args.repeats + 1):
        gc.collect()
        have_peak = _reset_peak()
        base = _status_kb("VmRSS")
        ru0 = resource.getrusage(resource.RUSAGE_SELF)
        t0 = time.perf_counter()
        out = run()
        dt = time.perf_counter() - t0
        ru1 = resource.getrusage(resource.RUSAGE_SELF)
        cpus.append(ru1.ru_utime - ru0.ru_utime + ru1.ru_stime - ru0.ru_stime)
        systems.append(ru1.ru_stime - ru0.ru_stime)  # the kernel's share (page faults)
        faults.append(ru1.ru_minflt - ru0.ru_minflt)  # pages the call touched first
        rep = _reported_kib()
        reported.append(None if rep is None or rep_prev is None else rep - rep_prev)
        rep_prev = rep
        peak = _status_kb("VmHWM") - base if have_peak else None
        res = measure(out)
        del out
        peaks.append(peak)
        if r == 0:  # the first full-size call of the process, reported apart
            first_times.append(dt)
            first_cpus.append(cpus.pop())
            first_faults.append(faults.pop())
            systems.pop()
            reported.pop()
        else:
            times.append(dt)
        if result is None:
            result = res
        elif (res[0], res[1]) != (result[0], result[1]):
            raise RuntimeError("%s: output changed between repetitions" % label)
    ntri, nvert, nbytes, extra = result
    extra.pop("keep", None)
    json.dump({"regime": args.child_regime, "allocator_keeps": keeps,
               "times": times, "cpu_times": cpus, "sys_times": systems,
               "minflt": faults, "reported_kib": reported,
               "first_times": first_times,
               "first_cpu_times": first_cpus, "first_minflt": first_faults,
               "peak_extra_kb": None if None in peaks else max(peaks),
               "triangles": ntri, "vertices": nvert, "output_bytes": nbytes,
               "input_bytes": int(a.nbytes), "rss_input_kb": rss_input - rss_before_input,
               "floor_times": floor_times, "floor_sum": fsum, "numpy_sum": nsum,
               "numpy_sum_times": numpy_times, "floor_impl": "C" if floor_lib else "numpy",
               "extra": extra}, sys.stdout)


# ------------------------------------------------------------------------ the parent

def child_command(args, extractor, vol_path, iso, threads, repeats, regime):
    """The command line and environment of one child process (one round)."""
    cmd = [sys.executable, os.path.abspath(__file__), "--child-extractor", extractor,
           "--child-volume", vol_path, "--child-iso", repr(iso), "--child-threads",
           str(threads), "--repeats", str(repeats), "--child-regime", regime]
    if args.lib_dir:
        cmd += ["--lib-dir", args.lib_dir]
    if args.floor_lib:
        cmd += ["--floor-lib", args.floor_lib]
    return cmd, regime_env(regime)


def run_child(args, extractor, vol_path, iso, threads, repeats, regime):
    cmd, env = child_command(args, extractor, vol_path, iso, threads, repeats, regime)
    t0 = time.perf_counter()
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       timeout=args.child_timeout, env=env)
    if p.returncode != 0:
        msg = (p.stderr.strip().splitlines() or ["exit status %d" % p.returncode])[-1]
        return {"error": msg}
    r = json.loads(p.stdout)
    r["child_seconds"] = time.perf_counter() - t0  # the whole child: what a round costs
    if r["regime"] != regime:
        return {"error": "the child measured regime %r, not %r" % (r["regime"], regime)}
    return r


def plan(args):
    """The list of volumes (field, size, dtype) and the per-volume extractor policy."""
    if args.smoke:
        vols = [("sphere", 24, "f32"), ("noise", 24, "u8")]
    elif args.quick:
        vols = [(f, 256, "f32") for f in ("sphere", "gyroid", "noise")]
        vols += [("sphere", 512, "f32"), ("noise", 512, "u8")]
    else:
        vols = [(f, n, d) for n in (128, 256, 512) for f in ("sphere", "gyroid", "noise")
                for d in ("f32", "u8")]
        vols += [("colin27", 0, "u8"), ("colin27", 0, "f32")]
    if args.fields:
        keep = set(args.fields.split(","))
        vols = [v for v in vols if v[0] in keep]
    if args.sizes:
        keep = {int(s) for s in args.sizes.split(",")}
        vols = [v for v in vols if v[1] in keep or v[0] == "colin27"]
    if args.dtypes:
        keep = set(args.dtypes.split(","))
        vols = [v for v in vols if v[2] in keep]
    return vols


def quick_policy(args, name, field, size, dtype):
    """Which measurements a mode makes: a list of (regime, rounds, calls), empty for
    none; rounds None for the default, ONCE (one round, at one thread; isomend at all
    threads) or a cap on the default; calls None for --calls.

    Full and smoke modes measure every extractor in both regimes.  Quick mode stays
    under two minutes on an idle machine with the goal's comparison (isomend DMC
    against Flying Edges geometry) in both regimes on every volume, warm (the
    headline) in more rounds than cold: isomend warm in 3 rounds, cold in 1 (it maps
    its own arrays in either regime: its cold calls differ little from its warm ones);
    Flying Edges warm in 2 rounds of 2 calls, cold in 1 round of 1 call (its cold calls
    are all alike: each one's arrays are fresh pages, the first call's too, which every
    child reports beside).  Warm only: isomend without normals once, at one thread,
    on the 256^3 fields; the other extractors (Flying Edges with normals among them)
    once, at one thread, on the 256^3 sphere, one timed call; the uint8 noise volume
    of the memory goal with isomend alone, once.  isomend recycling its previous mesh
    is left to full mode."""
    if not args.quick:
        return [(regime, None, None) for regime in REGIMES]
    goal = (name in ("isomend", "fe") and size in (256, 512)
            and (field, dtype) != ("noise", "u8"))
    if goal and name == "fe":
        return [("warm", 2, 2), ("cold", 1, 1)]
    if goal:
        return [("warm", None, None), ("cold", 1, None)]
    if (field, size, dtype) == ("noise", 512, "u8"):
        return [("warm", ONCE, None)] if name == "isomend" else []
    if name == "isomend-recycle" or size == 512:
        return []
    if name == "isomend-geom":
        return [("warm", ONCE, None)]
    if (field, size) == ("sphere", 256):
        return [("warm", ONCE, None if name.startswith("isomend") else 1)]
    return []


def volume_jobs(args, peers, field, n, dtype, t, thread_counts, repeats):
    """The (extractor, regime, rounds, calls) measured on one volume at t threads,
    in the order a round runs them: each extractor's regimes one after the other."""
    jobs = []
    for ext in peers:
        _label, _setup, parallel = EXTRACTORS[ext]
        if not parallel and t != thread_counts[0]:
            continue  # single-threaded: its 1-thread time stands for every count
        for regime, rounds, calls in quick_policy(args, ext, field, n, dtype):
            if regime not in getattr(args, "regimes", REGIMES):
                continue
            if rounds is ONCE:
                if t != (thread_counts[-1] if ext == "isomend" else thread_counts[0]):
                    continue  # measured once: at 1 thread (isomend: all threads)
                rounds = 1
            jobs.append((ext, regime, min(rounds, repeats) if rounds else repeats,
                         calls or args.calls))
    return jobs


def machine_info(outputs=()):
    info = {"python": platform.python_version(), "cpus": os.cpu_count()}
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    info["cpu"] = line.split(":", 1)[1].strip()
                    break
        with open("/proc/meminfo") as f:
            info["mem_gb"] = round(int(f.readline().split()[1]) / 1024 / 1024, 1)
        with open("/etc/debian_version") as f:
            info["debian"] = f.read().strip()
        info["loadavg"] = os.getloadavg()
    except OSError:
        pass
    try:
        import numpy
        import vtkmodules.vtkCommonCore as cc
        info["numpy"] = numpy.__version__
        info["vtk"] = cc.vtkVersion.GetVTKVersion()
        info["vtk_smp"] = cc.vtkSMPTools.GetBackend()
    except ImportError:
        pass
    for mod, key in (("skimage", "skimage"), ("pyopenvdb", "openvdb")):
        try:
            m = __import__(mod)
            info[key] = getattr(m, "__version__", None) or ".".join(
                str(x) for x in getattr(m, "LIBRARY_VERSION", ()))
        except ImportError:
            pass
    try:
        # "-dirty" when a tracked file differs, except this run's own outputs
        # (docs/bench-results.md is tracked and rewritten by every run)
        rev = subprocess.run(["git", "-C", ROOT, "describe", "--always"],
                             capture_output=True, text=True).stdout.strip()
        exclude = [":(exclude)" + os.path.relpath(os.path.abspath(f), ROOT)
                   for f in outputs if f]
        changed = subprocess.run(["git", "-C", ROOT, "status", "--porcelain",
                                  "--untracked-files=no", "--", "."] + exclude,
                                 capture_output=True, text=True).stdout.strip()
        if rev:
            info["git"] = rev + ("-dirty" if changed else "")
    except OSError:
        pass
    return info


def measure_volume(args, peers, field, n, dtype, vol_path, iso, t, thread_counts, repeats):
    """Measures every extractor on one volume at t threads, in rounds: round r runs
    each (extractor, regime) once, in a fresh child, so that the extractors and
    regimes being compared take turns and a change of load on a shared machine hits
    them alike."""
    jobs = volume_jobs(args, peers, field, n, dtype, t, thread_counts, repeats)
    acc = {}
    for rnd in range(max([reps for _e, _g, reps, _c in jobs] or [0])):
        for ext, regime, reps, calls in jobs:
            a = acc.setdefault((ext, regime), {})
            if rnd >= reps or "error" in a:
                continue
            r = run_child(args, ext, vol_path, iso, t, calls, regime)
            if "error" in r:
                a.clear()
                a["error"] = r["error"]
            elif not a:
                a.update(r)
            elif (r["triangles"], r["vertices"]) != (a["triangles"], a["vertices"]):
                a.clear()
                a["error"] = "output changed between runs"
            else:
                a["child_seconds"] += r["child_seconds"]
                for key in ("times", "cpu_times", "sys_times", "minflt", "reported_kib",
                            "first_times", "first_cpu_times", "first_minflt", "floor_times",
                            "numpy_sum_times"):
                    a[key] = a[key] + r[key]
                if a["peak_extra_kb"] is not None and r["peak_extra_kb"] is not None:
                    a["peak_extra_kb"] = max(a["peak_extra_kb"], r["peak_extra_kb"])
                if a["allocator_keeps"] != r["allocator_keeps"]:
                    a["allocator_keeps"] = None  # --check reports it
    out = []
    for ext, regime, reps, calls in jobs:
        label, _setup, parallel = EXTRACTORS[ext]
        r = acc[(ext, regime)]
        r.update({"field": field, "size": n, "dtype": dtype, "extractor": ext, "label": label,
                  "regime": regime, "threads": t, "iso": iso, "parallel": parallel,
                  "repeats": reps, "calls": calls})
        if "times" in r:
            r["median"] = statistics.median(r["times"])
            r["min"] = min(r["times"])
            r["cpu"] = statistics.median(r["cpu_times"])
            r["sys"] = statistics.median(r["sys_times"])
            r["user"] = statistics.median([c - k for c, k in zip(r["cpu_times"],
                                                                   r["sys_times"])])
            r["faults"] = statistics.median(r["minflt"])
            r["floor"] = statistics.median(r["floor_times"])
            r["first"] = statistics.median(r["first_times"])
            r["first_faults"] = statistics.median(r["first_minflt"])
            print("[bench]   %-32s %s %d thr: %8.1f ms (CPU %7.1f ms, kernel %6.1f, %6d "
                  "faults) %9d tri  floor %.1f ms"
                  % (label, regime, t, 1e3 * r["median"], 1e3 * r["cpu"], 1e3 * r["sys"],
                     r["faults"], r["triangles"], 1e3 * r["floor"]),
                  file=sys.stderr, flush=True)
        else:
            print("[bench]   %-32s %s %d thr: FAILED: %s" % (label, regime, t, r["error"]),
                  file=sys.stderr, flush=True)
        out.append(r)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument("--quick", action="store_true", help="the goal volumes, under two minutes")
    mode.add_argument("--smoke", action="store_true", help="tiny volumes, a few seconds")
    ap.add_argument("--fields", help="comma list of %s" % ",".join(FIELDS))
    ap.add_argument("--sizes", help="comma list of edge lengths (128,256,512)")
    ap.add_argument("--dtypes", help="comma list of f32,u8")
    ap.add_argument("--threads", help="comma list of thread counts (default 1 and all cores)")
    ap.add_argument("--repeats", type=int, help="rounds (child processes) per measurement")
    ap.add_argument("--calls", type=int,
                    help="timed calls per child process, after its first call (default 3; "
                         "2 with --quick, 1 with --smoke)")
    ap.add_argument("--peers", default="all",
                    help="comma list of %s, or all"
                    % ",".join(ALL_PEERS))
    ap.add_argument("--regimes", default=",".join(REGIMES),
                    help="memory regimes to measure, a comma list of warm (the headline: "
                         "the allocator keeps freed memory) and cold (glibc's default); "
                         "default both")
    ap.add_argument("--lib-dir", help="folder with libisomend.so (else $ISOMEND_LIB_DIR)")
    ap.add_argument("--floor-lib", help="libisomend_bench_floor.so (else numpy's sum)")
    ap.add_argument("--cache-dir", help="where generated volumes are kept "
                    "(default ~/.cache/isomend-bench; the smoke test uses a temporary one)")
    ap.add_argument("--out", help="markdown table to write (atomically)")
    ap.add_argument("--json", help="raw results to write")
    ap.add_argument("--check", action="store_true",
                    help="fail unless every extractor ran and the counts are consistent")
    ap.add_argument("--child-timeout", type=float, default=1800)
    ap.add_argument("--child-extractor", help=argparse.SUPPRESS)
    ap.add_argument("--child-volume", help=argparse.SUPPRESS)
    ap.add_argument("--child-iso", type=float, help=argparse.SUPPRESS)
    ap.add_argument("--child-threads", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--child-regime", choices=REGIMES, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)

    if args.child_extractor:
        child_main(args)
        return 0

    started = time.time()
    for path, what in ((args.lib_dir, "--lib-dir"), (args.floor_lib, "--floor-lib")):
        if path and not os.path.exists(path):
            print("bench.py: %s %s does not exist" % (what, path), file=sys.stderr)
            return 2
    if args.lib_dir:
        args.lib_dir = os.path.abspath(args.lib_dir)
    if args.floor_lib:
        args.floor_lib = os.path.abspath(args.floor_lib)
    peers = ALL_PEERS if args.peers == "all" else args.peers.split(",")
    for p in peers:
        if p not in EXTRACTORS:
            print("bench.py: --peers: unknown extractor %r (known: %s)"
                  % (p, ", ".join(EXTRACTORS)), file=sys.stderr)
            return 2
    args.regimes = args.regimes.split(",")
    if not args.regimes or any(g not in REGIMES for g in args.regimes):
        print("bench.py: --regimes: a comma list of %s" % ", ".join(REGIMES), file=sys.stderr)
        return 2
    ncpu = os.cpu_count() or 1
    if args.threads:
        try:
            thread_counts = [int(t) for t in args.threads.split(",")]
        except ValueError:
            thread_counts = [0]
        if any(t < 1 for t in thread_counts):
            print("bench.py: --threads %r: expected positive integers" % args.threads,
                  file=sys.stderr)
            return 2
    else:
        thread_counts = sorted({1, ncpu})
    repeats = args.repeats or (1 if args.smoke else 3 if args.quick else 5)
    if args.calls is None:
        args.calls = 1 if args.smoke else 2 if args.quick else 3
    if args.calls < 1:
        print("bench.py: --calls must be >= 1", file=sys.stderr)
        return 2
    if repeats < 1:
        print("bench.py: --repeats must be >= 1", file=sys.stderr)
        return 2

    tmp_cache = None
    if args.cache_dir:
        cache = args.cache_dir
    elif args.smoke:
        cache = tmp_cache = tempfile.mkdtemp(prefix="isomend-bench-")
    else:
        cache = os.path.join(os.environ.get("XDG_CACHE_HOME",
                                            os.path.expanduser("~/.cache")), "isomend-bench")
    os.makedirs(cache, exist_ok=True)

    info = machine_info((args.out, args.json))
    info["mode"] = "smoke" if args.smoke else "quick" if args.quick else "full"
    info["command"] = "bench/bench.py " + " ".join(argv if argv is not None else sys.argv[1:])
    info["started"] = datetime.datetime.utcnow().strftime("%Y-%m-%d %H:%M UTC")
    info["repeats"] = repeats
    info["calls"] = args.calls
    if args.floor_lib:
        info["page_cost"] = page_cost(args.floor_lib, 16 if args.smoke else 256)
    start_kib = _reported_kib()
    if start_kib is not None:
        info["page_reporting"] = {"order": _page_reporting("page_reporting_order"),
                                  "min_free_ms": _page_reporting("min_free_ms"),
                                  "start_kib": start_kib}
    results = []
    try:
        for (field, n, dtype) in plan(args):
            try:
                t0 = time.perf_counter()
                vol_path, iso = volume_file(cache, field, n, dtype)
                gen = time.perf_counter() - t0
            except (RuntimeError, OSError, ImportError) as e:
                print("bench.py: %s: %s" % (field, e), file=sys.stderr)
                results.append({"field": field, "size": n, "dtype": dtype, "error": str(e)})
                continue
            print("[bench] %s %s %s (ready in %.1f s)" % (field, n or "", dtype, gen),
                  file=sys.stderr, flush=True)
            for t in thread_counts:
                results += measure_volume(args, peers, field, n, dtype, vol_path, iso, t,
                                          thread_counts, repeats)
    finally:
        if tmp_cache:
            shutil.rmtree(tmp_cache, ignore_errors=True)
    info["seconds"] = round(time.time() - started, 1)
    end_kib = _reported_kib()
    if info.get("page_reporting") and end_kib is not None:
        info["page_reporting"]["run_kib"] = end_kib - info["page_reporting"]["start_kib"]
    info["loadavg_end"] = os.getloadavg()

    if args.json:
        _write_atomic(args.json, json.dumps({"machine": info, "results": results}, indent=1))
    text = render(info, results, thread_counts)
    if args.out:
        _write_atomic(args.out, text)
    else:
        sys.stdout.write(text)
    print("[bench] done in %.0f s" % info["seconds"], file=sys.stderr)
    if args.check:
        problems = check(results, peers, args.regimes)
        if args.floor_lib and not (info.get("page_cost") and min(info["page_cost"]) > 0):
            problems.append("the fresh-memory cost was not measured (isomend_bench_page_cost)")
        for p in problems:
            print("bench.py: check: %s" % p, file=sys.stderr)
        return 1 if problems else 0
    return 0


def _write_atomic(path, text):
    d = os.path.dirname(os.path.abspath(path))
    os.makedirs(d, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=d)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def check(results, peers, regimes=REGIMES):
    """Consistency of a run (the smoke test): every measurement succeeded, the
    floor read every voxel, isomend's mesh has Flying Edges' vertices (one per
    intersected edge), the Python wrapper and the geometry-only run give the
    library's mesh, and the mesh does not depend on the thread count."""
    problems = []
    by = {}
    reporting = _reported_kib() is not None
    for r in results:
        if "error" in r:
            problems.append("%s %s %s %s: %s" % (r["field"], r["size"], r["dtype"],
                                                  r.get("extractor", "volume"), r["error"]))
            continue
        by[(r["field"], r["size"], r["dtype"], r["extractor"], r["regime"], r["threads"])] = r
        # The regime is the one the child's allocator was in (None: not known there).
        if r.get("allocator_keeps") is not None and \
                r["allocator_keeps"] != (r["regime"] == "warm"):
            problems.append("%s %s: measured as %s, but the child's allocator %s freed "
                            "memory" % (r["label"], r["regime"], r["regime"],
                                        "kept" if r["allocator_keeps"] else "did not keep"))
        if len(r.get("minflt", [])) != len(r["times"]):
            problems.append("%s: page faults not recorded per call" % r["label"])
        if abs(r["floor_sum"] - r["numpy_sum"]) > 1e-4 * max(1.0, abs(r["numpy_sum"])) + 1e-3 * \
                r["input_bytes"]:
            problems.append("%s: floor sum %g != numpy sum %g" % (r["label"], r["floor_sum"],
                                                                  r["numpy_sum"]))
        if not r["triangles"] and r["field"] != "colin27":
            problems.append("%s on %s: no triangles" % (r["label"], r["field"]))
        rep = r.get("reported_kib", [])
        if len(rep) != len(r["times"]) or (reporting and None in rep):
            problems.append("%s: memory reported to the host not recorded per call" % r["label"])
    for key, r in by.items():
        f, n, d, ext, regime, t = key
        if ext == "isomend":
            for other in ("isomend-geom", "isomend-recycle", "isomend-py"):
                o = by.get((f, n, d, other, regime, t))
                if o and (o["triangles"], o["vertices"]) != (r["triangles"], r["vertices"]):
                    problems.append("%s %d %s: %s differs from isomend (%d/%d vs %d/%d)" % (
                        f, n, d, other, o["triangles"], o["vertices"], r["triangles"],
                        r["vertices"]))
            # Flying Edges also shares one vertex per intersected edge: same vertices.
            # (Its table triangulates some inverted cases with more triangles, so
            # triangle counts differ by design; they stay within 15 %.)
            fe = by.get((f, n, d, "fe", regime, t))
            if fe:
                if r["vertices"] != fe["vertices"]:
                    problems.append("%s %d %s: isomend has %d vertices, Flying Edges %d" % (
                        f, n, d, r["vertices"], fe["vertices"]))
                if abs(r["triangles"] - fe["triangles"]) > 0.15 * fe["triangles"]:
                    problems.append("%s %d %s: isomend %d triangles, Flying Edges %d" % (
                        f, n, d, r["triangles"], fe["triangles"]))
            base = by.get((f, n, d, "isomend", "warm", 1))
            if base and (base["triangles"], base["vertices"]) != (r["triangles"], r["vertices"]):
                problems.append("%s %d %s: isomend output depends on the thread count or "
                                "the regime" % (f, n, d))
    for p in peers:
        for regime in regimes:
            if not any(k[3] == p and k[4] == regime for k in by):
                problems.append("extractor %s never ran %s" % (p, regime))
    return problems


# ------------------------------------------------------------------------ rendering

def _ms(x):
    if x is None:
        return "—"
    x *= 1e3
    return "%.0f" % x if x >= 100 else "%.1f" % x if x >= 1 else "%.2f" % x


def _mb(kb):
    return "—" if kb is None else "%.0f" % (kb / 1024) if kb >= 10240 else "%.1f" % (kb / 1024)


def _count(n):
    return "%.2f M" % (n / 1e6) if n >= 1e5 else "%d" % n


def _vol_name(f, n, d):
    return "%s %s" % (f, d) if f == "colin27" else "%s %d³ %s" % (f, n, d)


def _rounds_note(info, results):
    """How rows depart from the run's rounds x calls: '; vtkFlyingEdges3D geometry: warm
    2 rounds of 2 calls, cold 1 of 1' (single rounds of the default calls are marked ¹)."""
    combos = {}
    for r in results:
        if "repeats" not in r:
            continue
        rc = (r["repeats"], r["calls"])
        if rc == (info["repeats"], info["calls"]) or rc == (1, info["calls"]):
            continue
        combos.setdefault(r["label"], {}).setdefault(r["regime"], set()).add(rc)
    parts = []
    for label in sorted(combos):
        parts.append("%s: %s" % (label, ", ".join(
            "%s %s" % (regime, " or ".join("%d round%s of %d call%s" % (
                n, "" if n == 1 else "s", c, "" if c == 1 else "s") for n, c in sorted(rcs)))
            for regime, rcs in sorted(combos[label].items(), key=lambda x: REGIMES.index(x[0])))))
    return "".join("; " + p for p in parts)


def _faults(r):
    return "—" if r is None else "%.0f" % r["faults"]


def _regimes_paragraph(info, by, vols, thread_counts):
    """Why warm and cold differ, with this run's figures: the per-call faults of
    Flying Edges on the first goal volume and their price on this machine."""
    parts = []
    w = parts.append
    w("**Memory regimes.** *Warm* (the headline; the goals are judged on it): every "
      "extractor runs in a child whose allocator keeps the memory a call frees "
      "(`GLIBC_TUNABLES=%s`), and the timed calls come back to back after a full-size first "
      "call, as in a program that extracts one surface after another. *Cold* (marked so "
      "wherever it appears): glibc's default allocator, which hands large freed arrays back "
      "to the kernel (unmapped, or trimmed from the heap), so that every call touches its "
      "arrays as fresh pages again, one minor fault per 4 KiB page, each page zeroed by the "
      "kernel. The first call of a process, fresh memory in either regime, is reported "
      "apart. isomend maps its output and work arrays itself, on 2 MiB pages, and unmaps "
      "them when a mesh is destroyed: it pays for its fresh output in both regimes, as it "
      "does in any program (few faults, one per 2 MiB page, but the kernel zeroes every "
      "page, and gets it back from the host first where the host had taken it: its "
      "*kernel ms*). *faults* = the median minor page faults of a call (getrusage "
      "`ru_minflt`); *kernel ms* = the median system time of a call." % ":".join(WARM_TUNABLES))
    pc = info.get("page_cost")
    for v in vols:
        t = thread_counts[0]
        fw, fc = by.get(v + ("fe", "warm", t)), by.get(v + ("fe", "cold", t))
        if not (fw and fc):
            continue
        mb = fc["faults"] * 4096 / 2**20
        w(" On the %s at %d thread%s Flying Edges took %.0f faults per cold call (%.0f MB of "
          "4 KiB pages)%s and %.0f per warm call: %s ms cold, %s ms warm (CPU time %s / %s "
          "ms)." % (_vol_name(*v), t, "" if t == 1 else "s", fc["faults"], mb,
                    ", %.0f ms at this run's %.3g ms/MB for 4 KiB pages" % (mb * pc[2], pc[2])
                    if pc else "", fw["faults"], _ms(fc["median"]), _ms(fw["median"]),
                    _ms(fc["cpu"]), _ms(fw["cpu"])))
        break
    if pc:
        w(" Where a 4 KiB fault is cheap (an ordinary machine, not a guest that traps to "
          "its host on every fault) the two regimes come closer; the warm figures leave the "
          "fault price out of every extractor's calls alike.")
    return "".join(parts) + "\n"


def render(info, results, thread_counts):
    out = []
    w = out.append
    w("# isomend benchmark results\n")
    w("Generated by `%s` (%s mode) on %s in %.0f s. "
      "**Do not edit: rerun the benchmark** (see docs/performance.md).\n"
      % (info.get("command"), info["mode"], info["started"], info["seconds"]))
    w("Machine: %s, %s cores, %s GB RAM, Debian %s (timings are medians of %d rounds — "
      "child processes — of %d timed calls each, single rounds where marked ¹%s). "
      "isomend %s (git %s); VTK %s (SMP backend %s), scikit-image %s, OpenVDB %s, numpy %s, "
      "Python %s.\n"
      % (info.get("cpu", "?"), info.get("cpus"), info.get("mem_gb"), info.get("debian", "?"),
         info["repeats"], info["calls"], _rounds_note(info, results),
         _first_extra(results, "version") or "?", info.get("git", "?"), info.get("vtk", "?"),
         info.get("vtk_smp", "?"), info.get("skimage", "?"), info.get("openvdb", "?"),
         info.get("numpy", "?"), info.get("python")))
    pc = info.get("page_cost")
    if pc:
        w("Fresh memory at the start of the run (the kernel zeroing the pages a process "
          "touches first): 2 MiB pages %.3g ms/MB the first time, %.3g ms/MB reused; 4 KiB "
          "pages %.3g ms/MB reused. A first time far above the reused figure means the host "
          "had taken the memory back (free page reporting); calls then pay that price on "
          "part of their output.\n" % (pc[0], pc[1], pc[2]))
    pr = info.get("page_reporting")
    if pr and "run_kib" in pr:
        w("Free page reporting: this VM's kernel handed %.0f MB of free memory back to its "
          "host during the run (page_reporting_order %s, min_free_ms %s).\n"
          % (pr["run_kib"] / 1024, pr.get("order"), pr.get("min_free_ms")))
    ok = [r for r in results if "times" in r]
    one = [r for r in ok if r["threads"] == 1]
    wall = sum(sum(r["times"]) for r in one)
    if wall > 0:
        share = sum(sum(r["cpu_times"]) for r in one) / wall
        w("Load: average %s at the start, %s at the end; the 1-thread calls got %.0f %% of a "
          "core on average (CPU time / wall time): %s\n" % (
              ", ".join("%.2f" % x for x in info.get("loadavg", ())),
              ", ".join("%.2f" % x for x in info.get("loadavg_end", ())), 100 * share,
              "the machine was not idle, compare the CPU-time ratios." if share < 0.9 else
              "the machine was close to idle."))
    by = {(r["field"], r["size"], r["dtype"], r["extractor"], r["regime"], r["threads"]): r
          for r in ok}
    vols = []
    for r in results:
        v = (r["field"], r["size"], r["dtype"])
        if v not in vols:
            vols.append(v)

    # Goal summary.
    w("## Goals\n")
    w("Goal 2: isomend DMC (normals, shared vertices, no holes) at least 2x faster than "
      "vtkFlyingEdges3D geometry-only at equal threads on every field at 256³ and 512³, and "
      "within 4x of the memory-read floor on the sphere. Floor = sum of every voxel by a C "
      "loop at the same thread count, same process, same array. **The goals are evaluated "
      "on the warm figures**; the cold ones are beside them, labelled *cold*.\n")
    w(_regimes_paragraph(info, by, vols, thread_counts))
    w("Three views of the warm runs, because the machine may be shared: the median wall "
      "time (the spec's measure), the CPU time the process used during the call (user + "
      "system, all threads; at 1 thread it is the least sensitive to other jobs, at 2 "
      "threads it includes TBB's idle spinning), and its user part alone, the work of the "
      "call without the kernel's (page faults, zeroing the pages of fresh memory: the part "
      "that depends on the machine's price of fresh memory; the kernel splits the two by "
      "sampling at its clock tick, so it is approximate).\n")
    w("| volume | threads | isomend DMC+normals ms | FE geometry ms | speed-up vs FE, median "
      "(goal ≥ 2) | CPU time | user time | faults per call, isomend / FE | kernel ms, "
      "isomend / FE | floor ms | "
      "isomend / floor (goal ≤ 4 on the sphere) | cold: isomend / FE ms | cold: speed-up | "
      "cold: faults per call, isomend / FE | triangles |")
    w("|---" * 15 + "|")
    for v in vols:
        for t in thread_counts:
            i = by.get(v + ("isomend", "warm", t))
            fe = by.get(v + ("fe", "warm", t))
            if not i:
                continue
            ic, fc = by.get(v + ("isomend", "cold", t)), by.get(v + ("fe", "cold", t))
            goal_size = v[1] in (256, 512)

            def ratio(a, b, key, mark):
                # a call too short for the clock's tick (user time 0 on tiny volumes) has no ratio
                if not (a and b) or not a[key] > 0:
                    return "—"
                x = b[key] / a[key]
                return "%.2f%s" % (x, (" ✔" if x >= 2 else " ✘") if mark and goal_size else "")
            fl = i["median"] / i["floor"] if i["floor"] > 0 else float("inf")
            fmark = (" ✔" if fl <= 4 else " ✘") if v[0] == "sphere" and goal_size else ""
            w("| %s | %d | %s | %s | %s | %s | %s | %s / %s | %s / %s | %s | %.1f%s | %s / %s | "
              "%s | %s / %s | %s |" % (
                  _vol_name(*v), t, _ms(i["median"]), _ms(fe["median"]) if fe else "—",
                  ratio(i, fe, "median", True), ratio(i, fe, "cpu", False),
                  ratio(i, fe, "user", False), _faults(i), _faults(fe), _ms(i["sys"]),
                  _ms(fe["sys"]) if fe else "—", _ms(i["floor"]), fl,
                  fmark, _ms(ic["median"]) if ic else "—", _ms(fc["median"]) if fc else "—",
                  ratio(ic, fc, "median", False), _faults(ic), _faults(fc),
                  _count(i["triangles"])))
    w("")
    mem = [r for r in ok if r["extractor"] == "isomend" and r["regime"] == "warm"
           and r.get("peak_extra_kb") is not None]
    if mem:
        w("Goal 3, memory: peak resident memory of the extraction (input + the largest "
          "increase of RSS during the call; warm) against input + output mesh + 10 %.\n")
        w("| volume | threads | input MB | output MB | peak MB | limit MB | met |")
        w("|---|---|---|---|---|---|---|")
        for r in mem:
            inp = r["input_bytes"] / 2**20
            outp = r["output_bytes"] / 2**20
            peak = inp + r["peak_extra_kb"] / 1024
            lim = 1.1 * (inp + outp)
            w("| %s | %d | %.0f | %.0f | %.0f | %.0f | %s |" % (
                _vol_name(r["field"], r["size"], r["dtype"]), r["threads"], inp, outp, peak,
                lim, "✔" if peak <= lim else "✘"))
        w("")

    # Details per volume.
    w("## Every extractor, per volume\n")
    w("Times in ms (median), warm unless marked *(cold)*. Each child process (a round) "
      "makes 1 + N full-size calls and times the last N: *first call* is the first one, "
      "which pays for fresh memory in either regime (on this virtual machine, memory the "
      "host may have taken back; isomend's huge-page output arrays are the slowest to get "
      "back, see docs/performance.md). *speed-up* = the extractor's time / isomend "
      "DMC+normals' time at the same thread count in the same regime (> 1: isomend is "
      "faster). *faults* = minor page faults per timed call at %d thread%s. *extra MB* = the "
      "largest RSS increase during the call (output and temporaries; the input is already "
      "resident). Single-threaded peers (vtkMarchingCubes, scikit-image) run once at 1 "
      "thread: that time stands for every thread count.\n"
      % (thread_counts[0], "" if thread_counts[0] == 1 else "s"))
    for v in vols:
        errs = [r for r in results if (r["field"], r["size"], r["dtype"]) == v and "error" in r]
        rows = [r for r in ok if (r["field"], r["size"], r["dtype"]) == v]
        if not rows:
            w("### %s\n\nnot measured: %s\n" % (_vol_name(*v), "; ".join(
                r["error"] for r in errs) or "no result"))
            continue
        w("### %s — iso %g\n" % (_vol_name(*v), rows[0]["iso"]))
        floors = {t: statistics.median([r["floor"] for r in rows if r["threads"] == t])
                  for t in thread_counts if any(r["threads"] == t for r in rows)}
        head = "| extractor |"
        for t in thread_counts:
            head += " %d thr ms | speed-up | × floor |" % t
        head += " faults | triangles | vertices | extra MB | first call, %d thr ms |" \
            % thread_counts[0]
        w(head)
        w("|---" * (1 + 3 * len(thread_counts) + 5) + "|")
        kinds = []
        for r in rows:
            if (r["extractor"], r["regime"]) not in kinds:
                kinds.append((r["extractor"], r["regime"]))
        for ext, regime in kinds:
            any_r = next(r for r in rows if (r["extractor"], r["regime"]) == (ext, regime))
            line = "| %s%s |" % (any_r["label"], " *(cold)*" if regime == "cold" else "")
            for t in thread_counts:
                r = by.get(v + (ext, regime, t))
                if r is None and not any_r["parallel"]:
                    r = by.get(v + (ext, regime, thread_counts[0]))
                    note = " (1 thr)" if t != thread_counts[0] else ""
                else:
                    note = ""
                if r is None:
                    line += " not run | | |"
                    continue
                once = "¹" if r["repeats"] == 1 else ""
                iso_r = by.get(v + ("isomend", regime, t))
                sp = r["median"] / iso_r["median"] if iso_r else None
                fl = floors.get(t)
                line += " %s%s%s | %s | %s |" % (_ms(r["median"]), once, note,
                                                  "%.2f" % sp if sp else "—",
                                                  "%.1f" % (r["median"] / fl) if fl else "—")
            same = [x for x in rows if (x["extractor"], x["regime"]) == (ext, regime)]
            peak = max([x["peak_extra_kb"] for x in same if x["peak_extra_kb"] is not None]
                       or [None], key=lambda x: x or 0)
            r1 = by.get(v + (ext, regime, thread_counts[0]))
            line += " %s | %s | %s | %s | %s |" % (_faults(r1), _count(any_r["triangles"]),
                                                   _count(any_r["vertices"]), _mb(peak),
                                                   _ms(r1["first"]) if r1 else "—")
            w(line)
        w("| memory-read floor (%s sum) |" % rows[0]["floor_impl"] +
          "".join(" %s | | |" % _ms(floors.get(t)) for t in thread_counts) + " | | | | |")
        np_t = statistics.median([min(r["numpy_sum_times"]) for r in rows])
        w("\nnumpy `a.sum(dtype=float64)` of the same array: %s ms (1 thread).\n" % _ms(np_t))
        for r in errs:
            w("- %s%s at %s threads: failed: %s" % (
                r.get("label", r.get("extractor")),
                " (cold)" if r.get("regime") == "cold" else "", r.get("threads"), r["error"]))
        if errs:
            w("")
    w("## Fields\n")
    for f in FIELDS:
        if any(v[0] == f for v in vols):
            w("- **%s**: %s; uint8 variants: round(127.5 + %s f), clipped, iso 127.5." % (
                f, field_description(f), U8_SCALE.get(f, "—")) if f != "colin27" else
              "- **%s**: %s; float32 variant: the same values as float32." % (
                  f, field_description(f)))
    w("")
    w("OpenVDB's time includes `copyFromArray` (dense array to a sparse grid) since every "
      "other extractor starts from the same dense array; its mesh is dual (one vertex per "
      "cell, quads counted as 2 triangles). scikit-image always computes normals. "
      "Flying Edges' and isomend's meshes share one vertex per intersected edge; isomend "
      "adds the mending quads (2 triangles per inverted combination).\n")
    return "\n".join(out)


def _first_extra(results, key):
    for r in results:
        if key in r.get("extra", {}):
            return r["extra"][key]
    return None


if __name__ == "__main__":
    sys.exit(main())
