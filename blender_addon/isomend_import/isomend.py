"""isomend: hole-free isosurface meshes from volumes (Python/ctypes binding).

This module is plain Python (ctypes + numpy, no bpy): the Blender add-on uses
it, and so can any script::

    import numpy as np, isomend
    vol = np.load("ct.npy")                    # array[z, y, x]: x varies fastest
    mesh = isomend.extract(vol, 300.0, spacing=(0.5, 0.5, 1.2), pad=True)
    mesh.positions   # (V, 3) float32, world x, y, z
    mesh.normals     # (V, 3) float32 unit gradient normals (None if normals=False)
    mesh.triangles   # (T, 3) uint32 vertex indices, counter-clockwise seen from outside
    mesh.origins     # (T,) uint8: 0 table, 1 Durst quad, 2 DMC mending quad
    mesh.stats       # dict: cubes, case_histogram, ambiguous_faces, ...
    mesh.check()     # dict: the continuity checker's report (holes, non-manifold edges)

    with isomend.open_source("scan/") as src:  # folder, glob, pattern, file list, multi-page TIFF
        print(src.dims, src.dtype, src.spacing, src.analyse()["suggested_iso"])
        print(src.geometry)                    # evenly spaced slices?  gaps, tilt, warning
        mesh = src.extract()                   # iso: the importer's suggestion (Otsu)
    mesh = isomend.extract_source("scan/", iso=None, method="dmc")   # the same in one call

    small, report = mesh.decimate(ratio=0.2)  # also mesh.smooth(5), mesh.clean(min_triangles=100)
    mesh = isomend.extract(vol, 300.0, pad=True, min_component=100, smooth=5, decimate=0.2)

    # a label map (segmentation): one closed surface a label, all in one pass
    organs = isomend.extract_labels_source("seg.nii.gz", pad=True)   # {value: Mesh}
    for value, m in organs.items():
        print(value, m.name, m.color, m.voxels, m.triangle_count)
    organs = isomend.extract_labels(seg, labels=[1, 5], pad=True,     # a numpy integer array
                                    label_table="FreeSurferColorLUT.txt")

Axes.  A numpy volume is indexed ``array[z, y, x]`` by default (C order, x
fastest), which is the core's contiguous layout and how image stacks load
(slice, row, column).  ``axes="xyz"`` says the array is ``array[x, y, z]``
(e.g. a Fortran-order array from nibabel); any permutation of "xyz" names
which world axis each array axis is.  ``spacing`` and ``origin`` are always
given in world order (x, y, z), whatever ``axes`` is, and ``positions`` are
world (x, y, z).  No copy is made for any stride pattern, including
Fortran-order, sliced (``vol[::2]``) and reversed (``vol[:, ::-1]``) views:
the numpy strides are passed to the core.  Supported dtypes: uint8, int8,
uint16, int16, int32, float32, float64 are read in place; bool is read as
uint8; float16 is converted to float32 and uint32/int64/uint64 to float64 (a
copy); non-native byte order is converted (a copy).

Library lookup (done once, on first use):
  1. the folders in the environment variable ISOMEND_LIB_DIR (one folder, or
     several separated by ':' such as "build/libcore:build/io/slices"; an
     error if the library is not there: no silent fallback);
  2. ``lib/`` next to this file: the add-on zip, and the staged copy the
     build makes in ``<build>/blender_addon/isomend_import/`` (so
     ``sys.path.insert(0, "<build>/blender_addon/isomend_import")`` then
     ``import isomend`` works straight from a build tree);
  3. the dynamic linker's search path (LD_LIBRARY_PATH, an installed
     ``libisomend.so.0``).
The core (libisomend) is loaded at the first call; the slice importer
(libisomend_io, which pulls in its image libraries) only when a source is opened.

Errors.  A failed call raises ``IsomendError`` (a RuntimeError) carrying
``.status`` (the C status code), ``.status_name`` and a message that names the
parameter or, for sources, the file and the reason.  ``Cancelled`` (a subclass)
is raised when a progress callback asked to stop.  Bad Python arguments raise
ValueError/TypeError before anything reaches C.  An exception raised inside a
progress callback cancels the C call and is re-raised after it returns.

Progress callbacks are called as ``progress(stage, fraction)`` with stage one
of "open", "read", "analyse", "extract" and fraction in [0, 1], always from
the thread that made the call.  Return True to cancel.

Thread safety: the functions may be called from several threads at once
(ctypes releases the GIL during the C calls); a Source must be used by one
thread at a time.  ``ExtractJob`` runs extract_source() on a thread of the C
library's own and calls no Python code there: the way to keep a host's
interface running where Python threads are not allowed (Blender).
"""

import ctypes
import math
import os
import threading

import numpy as np

__all__ = [
    "IsomendError", "Cancelled", "LibraryNotFound", "Mesh", "Source",
    "extract", "check", "open_source", "extract_source", "extract_labels", "extract_labels_source",
    "methods", "available_methods", "version", "io_version", "io_image_libraries", "library_path", "io_library_path",
    "METHODS", "ORIGIN_TABLE", "ORIGIN_DURST", "ORIGIN_MEND",
]

# ------------------------------------------------------------ constants
# These mirror libcore/include/isomend.h and io/slices/include/isomend_io.h;
# tests/blender/test_wrapper.py compares them and the struct layouts with a
# program compiled against the headers.

STATUS_NAMES = {
    0: "OK", 1: "INVALID_ARGUMENT", 2: "BAD_DIMENSIONS", 3: "BAD_SPACING", 4: "BAD_ISO",
    5: "OUT_OF_MEMORY", 6: "TOO_LARGE", 7: "CANCELLED", 8: "THREAD", 9: "UNSUPPORTED",
}
ERR_CANCELLED = 7

IO_STATUS_NAMES = {
    0: "OK", 1: "INVALID_ARGUMENT", 2: "NOT_FOUND", 3: "UNREADABLE", 4: "CORRUPT",
    5: "MISMATCH", 6: "UNSUPPORTED", 7: "TOO_FEW_SLICES", 8: "TOO_LARGE",
    9: "OUT_OF_MEMORY", 10: "CANCELLED", 11: "EXTRACT", 12: "INTERNAL", 13: "SERIES",
}
IO_ERR_CANCELLED = 10

TYPE_U8, TYPE_I8, TYPE_U16, TYPE_I16, TYPE_I32, TYPE_F32, TYPE_F64 = range(7)
TYPE_U32 = 7  # ISOMEND_U32: label maps only (extract_labels)
_DTYPE_TO_TYPE = {
    np.dtype(np.uint8): TYPE_U8, np.dtype(np.int8): TYPE_I8,
    np.dtype(np.uint16): TYPE_U16, np.dtype(np.int16): TYPE_I16,
    np.dtype(np.int32): TYPE_I32, np.dtype(np.float32): TYPE_F32,
    np.dtype(np.float64): TYPE_F64,
}
_TYPE_TO_DTYPE = {v: k for k, v in _DTYPE_TO_TYPE.items()}
# The dtypes a label map is read in place with (bool as uint8).
_LABEL_DTYPE_TO_TYPE = {np.dtype(np.uint8): TYPE_U8, np.dtype(np.int8): TYPE_I8,
                        np.dtype(np.uint16): TYPE_U16, np.dtype(np.int16): TYPE_I16,
                        np.dtype(np.int32): TYPE_I32, np.dtype(np.uint32): TYPE_U32}

# Method ids as in isomend.h; the names come from the library itself.
METHODS = {"mc": 0, "durst": 1, "dmc": 2, "facial": 3, "gradient": 4,
           "asymptotic": 5, "tetra": 6, "mc33": 7}
METHOD_COUNT = 8

FLAG_NO_NORMALS = 1 << 0
FLAG_FLIP = 1 << 1
FLAG_PAD = 1 << 2
FLAG_NO_ORIGINS = 1 << 3
FLAG_SMALL_PAGES = 1 << 4

ORIGIN_TABLE, ORIGIN_DURST, ORIGIN_MEND = 0, 1, 2
ORIGIN_NAMES = ("table", "durst", "mend")

IO_CHANNEL_AUTO = -1
IO_CHANNEL_LUMA = -2
IO_STAGES = ("open", "read", "analyse", "extract")
IO_KIND_NAMES = ("folder", "glob", "pattern", "list", "multipage", "raw", "nrrd", "dicom")
IO_AXES_PATIENT, IO_AXES_GRID = 0, 1
IO_LEVEL_NAMES = ("otsu", "bone", "skin")
IO_HISTOGRAM_BINS = 16


# ------------------------------------------------------------ errors

class IsomendError(RuntimeError):
    """A C call failed: ``status`` is the code, ``status_name`` its name."""

    def __init__(self, message, status=None, status_name=None):
        super().__init__(message)
        self.status = status
        self.status_name = status_name


class Cancelled(IsomendError):
    """A progress callback asked to stop (returned True)."""


class LibraryNotFound(IsomendError, OSError):
    """libisomend or libisomend_io could not be loaded (the message lists where it looked)."""


# ------------------------------------------------------------ C structures

class Volume(ctypes.Structure):
    _fields_ = [
        ("data", ctypes.c_void_p),
        ("type", ctypes.c_int),
        ("dims", ctypes.c_int64 * 3),
        ("strides", ctypes.c_int64 * 3),
        ("spacing", ctypes.c_double * 3),
        ("origin", ctypes.c_double * 3),
        # NULL (a uniform grid) or 3 * dims[2] doubles: each slice's sample (0, 0, k)
        ("slice_origins", ctypes.c_void_p),
    ]


PROGRESS_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double)
IO_PROGRESS_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_int, ctypes.c_double)


class Options(ctypes.Structure):
    _fields_ = [
        ("iso", ctypes.c_double),
        ("method", ctypes.c_int),
        ("flags", ctypes.c_uint),
        ("threads", ctypes.c_int),
        ("progress", PROGRESS_FN),
        ("progress_user", ctypes.c_void_p),
    ]


class Stats(ctypes.Structure):
    _fields_ = [
        ("cubes", ctypes.c_uint64),
        ("case_histogram", ctypes.c_uint64 * 15),
        ("ambiguous_faces", ctypes.c_uint64),
        ("inverted_combinations", ctypes.c_uint64),
        ("triangles_by_origin", ctypes.c_uint64 * 3),
        ("nan_samples", ctypes.c_uint64),
        ("vertices", ctypes.c_uint64),
        ("triangles", ctypes.c_uint64),
    ]


class CheckReport(ctypes.Structure):
    _fields_ = [
        ("vertices", ctypes.c_uint64),
        ("triangles", ctypes.c_uint64),
        ("edges", ctypes.c_uint64),
        ("border_edges", ctypes.c_uint64),
        ("hole_edges", ctypes.c_uint64),
        ("hole_loops", ctypes.c_uint64),
        ("nonmanifold_edges", ctypes.c_uint64),
        ("misoriented_edges", ctypes.c_uint64),
        ("nonmanifold_vertices", ctypes.c_uint64),
        ("degenerate_triangles", ctypes.c_uint64),
        ("components", ctypes.c_uint64),
        ("euler", ctypes.c_int64),
    ]


class DecimateOptions(ctypes.Structure):
    _fields_ = [
        ("ratio", ctypes.c_double),
        ("target_triangles", ctypes.c_uint64),
        ("max_error", ctypes.c_double),
    ]


class DecimateReport(ctypes.Structure):
    _fields_ = [
        ("triangles_before", ctypes.c_uint64),
        ("triangles_after", ctypes.c_uint64),
        ("vertices_before", ctypes.c_uint64),
        ("vertices_after", ctypes.c_uint64),
        ("target_triangles", ctypes.c_uint64),
        ("reached", ctypes.c_int),
        ("max_error", ctypes.c_double),
        ("mean_error", ctypes.c_double),
        ("collapses", ctypes.c_uint64),
        ("locked_vertices", ctypes.c_uint64),
        ("refused_topology", ctypes.c_uint64),
        ("refused_geometry", ctypes.c_uint64),
        ("refused_error", ctypes.c_uint64),
    ]


class SmoothReport(ctypes.Structure):
    _fields_ = [
        ("moved_vertices", ctypes.c_uint64),
        ("volume_before", ctypes.c_double),
        ("volume_after", ctypes.c_double),
        ("max_displacement", ctypes.c_double),
    ]


class CleanReport(ctypes.Structure):
    _fields_ = [
        ("components_before", ctypes.c_uint64),
        ("components_after", ctypes.c_uint64),
        ("triangles_removed", ctypes.c_uint64),
        ("vertices_removed", ctypes.c_uint64),
    ]


class IOOptions(ctypes.Structure):
    _fields_ = [
        ("first", ctypes.c_int64),
        ("count", ctypes.c_int64),
        ("step", ctypes.c_int64),
        ("channel", ctypes.c_int),
        ("spacing", ctypes.c_double * 3),
        ("origin", ctypes.c_double * 3),
        ("threads", ctypes.c_int),
        ("memory_limit", ctypes.c_uint64),
        ("raw_dims", ctypes.c_int64 * 3),
        ("raw_type", ctypes.c_int),
        ("raw_header", ctypes.c_uint64),
        ("raw_big_endian", ctypes.c_int),
        ("progress", IO_PROGRESS_FN),
        ("progress_user", ctypes.c_void_p),
        ("slice_positions", ctypes.c_void_p),   # const double *, NULL: evenly spaced
        ("slice_position_count", ctypes.c_size_t),
    ]


class IOGeometry(ctypes.Structure):
    _fields_ = [
        ("size", ctypes.c_size_t),
        ("uniform", ctypes.c_int),
        ("gap_median", ctypes.c_double),
        ("gap_min", ctypes.c_double),
        ("gap_max", ctypes.c_double),
        ("tilt_degrees", ctypes.c_double),
        ("max_offset", ctypes.c_double),
        ("long_gaps", ctypes.c_int64),
        ("uneven_gaps", ctypes.c_int64),
        ("warning", ctypes.c_char_p),
    ]


class IOSummary(ctypes.Structure):
    _fields_ = [
        ("min", ctypes.c_double),
        ("max", ctypes.c_double),
        ("samples", ctypes.c_uint64),
        ("nan_samples", ctypes.c_uint64),
        ("histogram", ctypes.c_uint64 * IO_HISTOGRAM_BINS),
        ("suggested_iso", ctypes.c_double),
        ("read_seconds", ctypes.c_double),
    ]


class IOSeries(ctypes.Structure):
    _fields_ = [
        ("size", ctypes.c_size_t),
        ("uid", ctypes.c_char_p),
        ("description", ctypes.c_char_p),
        ("modality", ctypes.c_char_p),
        ("number", ctypes.c_int64),
        ("files", ctypes.c_int64),
        ("images", ctypes.c_int64),
        ("columns", ctypes.c_int64),
        ("rows", ctypes.c_int64),
    ]


class IODicom(ctypes.Structure):
    _fields_ = [
        ("size", ctypes.c_size_t),
        ("modality", ctypes.c_char_p),
        ("series_uid", ctypes.c_char_p),
        ("description", ctypes.c_char_p),
        ("transfer_syntax", ctypes.c_char_p),
        ("transfer_syntax_name", ctypes.c_char_p),
        ("photometric", ctypes.c_char_p),
        ("bits_stored", ctypes.c_int),
        ("pixel_signed", ctypes.c_int),
        ("rescaled", ctypes.c_int),
        ("hounsfield", ctypes.c_int),
        ("rescale_slope", ctypes.c_double),
        ("rescale_intercept", ctypes.c_double),
        ("orientation", ctypes.c_double * 6),
        ("normal", ctypes.c_double * 3),
        ("position", ctypes.c_double * 3),
        ("files", ctypes.c_int64),
        ("multiframe", ctypes.c_int64),
        ("non_image", ctypes.c_int64),
        ("non_dicom", ctypes.c_int64),
        ("other_series", ctypes.c_int64),
        ("axes", ctypes.c_int),
    ]


# ------------------------------------------------------------ library loading

_HERE = os.path.dirname(os.path.abspath(__file__))
_lock = threading.Lock()
_core = None
_core_path = None
_io = None
_io_path = None

# File names tried in each folder, the SONAME first (it is what the add-on zip holds).
_CORE_NAMES = ("libisomend.so.0", "libisomend.so", "libisomend.dylib", "isomend.dll")
_IO_NAMES = ("libisomend_io.so.0", "libisomend_io.so", "libisomend_io.dylib", "isomend_io.dll")


def _search_dirs():
    env = os.environ.get("ISOMEND_LIB_DIR")
    if env:
        return [("ISOMEND_LIB_DIR", d) for d in env.split(os.pathsep) if d], True
    return [("next to the module", os.path.join(_HERE, "lib"))], False


def _load(names, what):
    dirs, exclusive = _search_dirs()
    tried = []
    for label, folder in dirs:
        for name in names:
            path = os.path.join(folder, name)
            if os.path.exists(path):
                try:
                    # RTLD_GLOBAL: libisomend_io finds the already loaded core by its SONAME.
                    return ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL), path
                except OSError as exc:
                    raise LibraryNotFound("cannot load %s %s: %s" % (what, path, exc)) from exc
        tried.append("%s (%s)" % (folder, label))
    if exclusive:
        raise LibraryNotFound("%s: none of %s found in ISOMEND_LIB_DIR=%s"
                              % (what, ", ".join(names[:2]), os.environ.get("ISOMEND_LIB_DIR")))
    for name in names[:2]:
        try:
            return ctypes.CDLL(name, mode=ctypes.RTLD_GLOBAL), name
        except OSError as exc:
            tried.append("%s via the dynamic linker (%s)" % (name, exc))
    raise LibraryNotFound("%s not found; looked in: %s. Set ISOMEND_LIB_DIR to the folder holding %s."
                          % (what, "; ".join(tried), names[0]))


def _declare(lib, name, restype, argtypes):
    fn = getattr(lib, name)
    fn.restype = restype
    fn.argtypes = argtypes
    return fn


def _core_lib():
    global _core, _core_path
    if _core is not None:
        return _core
    with _lock:
        if _core is not None:
            return _core
        lib, path = _load(_CORE_NAMES, "the isomend core library")
        P = ctypes.POINTER
        c_int, c_size, c_double, c_char_p = ctypes.c_int, ctypes.c_size_t, ctypes.c_double, ctypes.c_char_p
        _declare(lib, "isomend_status_string", c_char_p, [c_int])
        _declare(lib, "isomend_version", c_char_p, [])
        _declare(lib, "isomend_type_size", c_size, [c_int])
        _declare(lib, "isomend_type_name", c_char_p, [c_int])
        _declare(lib, "isomend_type_from_name", c_int, [c_char_p, P(c_int)])
        _declare(lib, "isomend_volume_init", None,
                 [P(Volume), ctypes.c_void_p, c_int, ctypes.c_int64, ctypes.c_int64, ctypes.c_int64])
        _declare(lib, "isomend_method_name", c_char_p, [c_int])
        _declare(lib, "isomend_method_from_name", c_int, [c_char_p, P(c_int)])
        _declare(lib, "isomend_method_available", c_int, [c_int])
        _declare(lib, "isomend_options_init", None, [P(Options)])
        _declare(lib, "isomend_extract", c_int,
                 [P(Volume), P(Options), P(ctypes.c_void_p), P(Stats)])
        _declare(lib, "isomend_mesh_destroy", None, [ctypes.c_void_p])
        _declare(lib, "isomend_mesh_vertex_count", c_size, [ctypes.c_void_p])
        _declare(lib, "isomend_mesh_triangle_count", c_size, [ctypes.c_void_p])
        _declare(lib, "isomend_mesh_positions", P(ctypes.c_float), [ctypes.c_void_p])
        _declare(lib, "isomend_mesh_normals", P(ctypes.c_float), [ctypes.c_void_p])
        _declare(lib, "isomend_mesh_triangles", P(ctypes.c_uint32), [ctypes.c_void_p])
        _declare(lib, "isomend_mesh_triangle_origins", P(ctypes.c_uint8), [ctypes.c_void_p])
        _declare(lib, "isomend_mesh_grid_box", None, [ctypes.c_void_p, P(c_double)])
        _declare(lib, "isomend_check", c_int,
                 [ctypes.c_void_p, c_size, ctypes.c_void_p, c_size, P(c_double), P(CheckReport)])
        _declare(lib, "isomend_mesh_check", c_int, [ctypes.c_void_p, P(CheckReport)])
        _declare(lib, "isomend_mesh_copy_transformed", c_int,
                 [ctypes.c_void_p, P(c_double), ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p,
                  ctypes.c_void_p])
        _declare(lib, "isomend_decimate_options_init", None, [P(DecimateOptions)])
        _declare(lib, "isomend_mesh_decimate", c_int,
                 [ctypes.c_void_p, P(DecimateOptions), P(ctypes.c_void_p), P(DecimateReport)])
        _declare(lib, "isomend_mesh_smooth", c_int,
                 [ctypes.c_void_p, c_int, P(ctypes.c_void_p), P(SmoothReport)])
        _declare(lib, "isomend_mesh_clean", c_int,
                 [ctypes.c_void_p, ctypes.c_uint64, ctypes.c_uint64, P(ctypes.c_void_p),
                  P(CleanReport)])
        _declare(lib, "isomend_labels_extract", c_int,
                 [P(Volume), P(ctypes.c_int64), c_size, P(Options), P(ctypes.c_void_p)])
        _declare(lib, "isomend_labels_count", c_size, [ctypes.c_void_p])
        _declare(lib, "isomend_labels_value", ctypes.c_int64, [ctypes.c_void_p, c_size])
        _declare(lib, "isomend_labels_voxels", ctypes.c_uint64, [ctypes.c_void_p, c_size])
        _declare(lib, "isomend_labels_take_mesh", ctypes.c_void_p, [ctypes.c_void_p, c_size])
        _declare(lib, "isomend_labels_destroy", None, [ctypes.c_void_p])
        _declare(lib, "isomend_meshes_smooth", c_int,
                 [P(ctypes.c_void_p), c_size, c_int, P(ctypes.c_void_p), P(SmoothReport)])
        _declare(lib, "isomend_meshes_decimate", c_int,
                 [P(ctypes.c_void_p), c_size, P(DecimateOptions), P(ctypes.c_void_p),
                  P(DecimateReport)])
        _declare(lib, "isomend_case_of", c_int, [ctypes.c_uint])
        _declare(lib, "isomend_case_triangles", c_int, [ctypes.c_uint, P(c_int)])
        _core, _core_path = lib, path
        return lib


def _io_lib():
    global _io, _io_path
    if _io is not None:
        return _io
    _core_lib()  # first: libisomend_io needs the core, found by its SONAME once loaded
    with _lock:
        if _io is not None:
            return _io
        lib, path = _load(_IO_NAMES, "the isomend slice importer library")
        P = ctypes.POINTER
        c_int, c_char_p, c_void_p = ctypes.c_int, ctypes.c_char_p, ctypes.c_void_p
        _declare(lib, "isomend_io_status_string", c_char_p, [c_int])
        _declare(lib, "isomend_io_version", c_char_p, [])
        _declare(lib, "isomend_io_image_libraries", c_char_p, [])
        _declare(lib, "isomend_io_options_init", None, [P(IOOptions)])
        _declare(lib, "isomend_io_create", c_int, [P(c_void_p)])
        _declare(lib, "isomend_io_destroy", None, [c_void_p])
        _declare(lib, "isomend_io_message", c_char_p, [c_void_p])
        _declare(lib, "isomend_io_open", c_int, [c_void_p, P(c_char_p), ctypes.c_size_t, P(IOOptions)])
        _declare(lib, "isomend_io_dims", c_int, [c_void_p, P(ctypes.c_int64)])
        _declare(lib, "isomend_io_type", c_int, [c_void_p, P(c_int)])
        _declare(lib, "isomend_io_volume_bytes", ctypes.c_uint64, [c_void_p])
        _declare(lib, "isomend_io_slice_bytes", ctypes.c_uint64, [c_void_p])
        _declare(lib, "isomend_io_spacing_source_name", c_char_p, [c_int])
        _declare(lib, "isomend_io_spacing", c_int, [c_void_p, P(ctypes.c_double), P(c_int)])
        _declare(lib, "isomend_io_origin", c_int, [c_void_p, P(ctypes.c_double)])
        _declare(lib, "isomend_io_kind_name", c_char_p, [c_int])
        _declare(lib, "isomend_io_source_kind", c_int, [c_void_p])
        _declare(lib, "isomend_io_format", c_char_p, [c_void_p])
        _declare(lib, "isomend_io_slice_path", c_char_p, [c_void_p, ctypes.c_int64])
        _declare(lib, "isomend_io_read", c_int, [c_void_p, c_void_p, ctypes.c_size_t])
        _declare(lib, "isomend_io_read_slice", c_int, [c_void_p, ctypes.c_int64, c_void_p, ctypes.c_size_t])
        _declare(lib, "isomend_io_load", c_int, [c_void_p, P(Volume), P(ctypes.c_double)])
        _declare(lib, "isomend_io_analyse", c_int, [c_void_p, P(IOSummary)])
        _declare(lib, "isomend_io_extract", c_int,
                 [c_void_p, P(Options), c_int, P(ctypes.c_double), P(c_void_p), P(Stats)])
        _declare(lib, "isomend_io_job_start", c_int,
                 [c_void_p, P(c_char_p), ctypes.c_size_t, P(IOOptions), P(Options), c_int, P(c_void_p)])
        _declare(lib, "isomend_io_job_poll", c_int, [c_void_p, P(c_int), P(ctypes.c_double)])
        _declare(lib, "isomend_io_job_cancel", None, [c_void_p])
        _declare(lib, "isomend_io_job_finish", c_int,
                 [c_void_p, P(ctypes.c_double), P(c_void_p), P(Stats)])
        _declare(lib, "isomend_io_set_series", c_int, [c_void_p, c_char_p])
        _declare(lib, "isomend_io_set_axes", c_int, [c_void_p, c_int])
        _declare(lib, "isomend_io_series_count", ctypes.c_int64, [c_void_p])
        _declare(lib, "isomend_io_series_get", c_int, [c_void_p, ctypes.c_int64, P(IOSeries)])
        _declare(lib, "isomend_io_series_chosen", ctypes.c_int64, [c_void_p])
        _declare(lib, "isomend_io_dicom_info", c_int, [c_void_p, P(IODicom)])
        _declare(lib, "isomend_io_world_transform", c_int, [c_void_p, P(ctypes.c_double), P(c_int)])
        _declare(lib, "isomend_io_geometry_info", c_int, [c_void_p, P(IOGeometry)])
        _declare(lib, "isomend_io_slice_origins", P(ctypes.c_double), [c_void_p])
        _declare(lib, "isomend_io_level_name", c_char_p, [c_int])
        _declare(lib, "isomend_io_level_value", c_int, [c_void_p, c_int, P(ctypes.c_double)])
        _declare(lib, "isomend_io_suggested_level", c_int, [c_void_p])
        _declare(lib, "isomend_io_labels_extract", c_int,
                 [c_void_p, P(ctypes.c_int64), ctypes.c_size_t, P(Options), P(c_void_p)])
        _declare(lib, "isomend_io_label_names_read", c_int, [c_void_p, c_char_p, P(c_void_p)])
        _declare(lib, "isomend_io_label_names_from", c_char_p, [c_void_p])
        _declare(lib, "isomend_io_label_name", c_int,
                 [c_void_p, ctypes.c_int64, c_char_p, ctypes.c_size_t, P(ctypes.c_uint8)])
        _declare(lib, "isomend_io_label_names_destroy", None, [c_void_p])
        _io, _io_path = lib, path
        return lib


def library_path():
    """Path of the loaded core library (loads it)."""
    _core_lib()
    return _core_path


def io_library_path():
    """Path of the loaded slice importer library (loads it and its image libraries)."""
    _io_lib()
    return _io_path


def version():
    """The core library's version string, e.g. "0.1.0"."""
    return _core_lib().isomend_version().decode()


def io_version():
    """The slice importer's version string."""
    return _io_lib().isomend_io_version().decode()


def io_image_libraries():
    """The image libraries the loaded slice importer reads with: "OpenImageIO
    2.4.7" (every format it reads), or "libtiff 4.5.0, OpenEXR 3.1.5, libpng
    1.6.39" for the portable build the Blender add-on carries (TIFF, OpenEXR,
    PNG)."""
    return _io_lib().isomend_io_image_libraries().decode()


def _status_text(status):
    text = _core_lib().isomend_status_string(status)
    return text.decode() if text else "unknown status %d" % status


def _raise_core(status, what):
    name = STATUS_NAMES.get(status, str(status))
    cls = Cancelled if status == ERR_CANCELLED else IsomendError
    raise cls("%s: %s" % (what, _status_text(status)), status, name)


# ------------------------------------------------------------ methods

def methods():
    """All method names the C API knows, in id order, with availability:
    [("mc", True), ("durst", True), ("dmc", True), ("facial", False), ...]."""
    lib = _core_lib()
    out = []
    for m in range(METHOD_COUNT):
        name = lib.isomend_method_name(m)
        if name:
            out.append((name.decode(), bool(lib.isomend_method_available(m))))
    return out


def available_methods():
    """Names of the methods this build implements."""
    return [name for name, ok in methods() if ok]


def _method_id(method):
    lib = _core_lib()
    if isinstance(method, (int, np.integer)) and not isinstance(method, bool):
        m = int(method)
        if not lib.isomend_method_name(m):
            raise ValueError("method: %d is not a method id (0..%d)" % (m, METHOD_COUNT - 1))
    elif isinstance(method, str):
        out = ctypes.c_int()
        if lib.isomend_method_from_name(method.lower().encode(), ctypes.byref(out)) != 0:
            raise ValueError("method: unknown method %r; known: %s"
                             % (method, ", ".join(n for n, _ in methods())))
        m = out.value
    else:
        raise TypeError("method: expected a name such as 'dmc' or an id, got %r" % (method,))
    if not lib.isomend_method_available(m):
        raise IsomendError("method: %r is not implemented in this build (available: %s)"
                           % (lib.isomend_method_name(m).decode(), ", ".join(available_methods())),
                           9, "UNSUPPORTED")
    return m


# ------------------------------------------------------------ progress

class _Progress:
    """Turns a Python progress callable into a C callback that never lets an
    exception escape (ctypes would swallow it): the exception cancels the C call
    and is re-raised by ``reraise()`` afterwards."""

    def __init__(self, fn, io=False):
        self.fn = fn
        self.error = None
        self.cancelled = False
        if io:
            self.c_fn = IO_PROGRESS_FN(self._io_call)
        else:
            self.c_fn = PROGRESS_FN(self._core_call)

    def _invoke(self, stage, fraction):
        if self.fn is None or self.error is not None:
            return 1 if self.error is not None else 0
        try:
            if self.fn(stage, float(fraction)):
                self.cancelled = True
                return 1
            return 0
        except BaseException as exc:  # KeyboardInterrupt too: cancel, re-raise later
            self.error = exc
            return 1

    def _core_call(self, _user, fraction):
        return self._invoke("extract", fraction)

    def _io_call(self, _user, stage, fraction):
        name = IO_STAGES[stage] if 0 <= stage < len(IO_STAGES) else str(stage)
        return self._invoke(name, fraction)

    def reraise(self):
        if self.error is not None:
            err, self.error = self.error, None
            raise err


# ------------------------------------------------------------ volumes

def _slice_positions(value, what, count=None):
    """A 1-D float64 array of slice positions (finite, strictly increasing;
    ``count`` of them if given), or ValueError naming ``what``."""
    z = np.array(value, dtype=np.float64).reshape(-1) if np.ndim(value) <= 1 else None
    if z is None:
        raise ValueError("%s: expected one z value per slice, got shape %s" % (what, np.shape(value)))
    if count is not None and len(z) != count:
        raise ValueError("%s: expected %d values (one per slice), got %d" % (what, count, len(z)))
    if len(z) < 2:
        raise ValueError("%s: expected at least 2 values, got %d" % (what, len(z)))
    if not np.isfinite(z).all():
        raise ValueError("%s: every value must be finite" % what)
    steps = np.diff(z)
    if not (steps > 0).all():
        k = int(np.argmin(steps > 0))
        raise ValueError("%s: must increase strictly (slice %d at %r, slice %d at %r)"
                         % (what, k, float(z[k]), k + 1, float(z[k + 1])))
    return z


def _label_array(array):
    """A label map's samples as the core reads them: the integer dtypes up to
    32 bits in place (bool as uint8); int64/uint64 and floats whose values are
    all whole numbers in the 32-bit range copied to uint32 (no negative value)
    or int32; anything else refused with the reason."""
    if not isinstance(array, np.ndarray):
        array = np.asarray(array)
    dt = array.dtype
    if dt == np.bool_:
        return array.view(np.uint8)
    if dt.kind not in "iuf":
        raise TypeError("labels: a label map holds integers, got dtype %s" % dt)
    if dt.kind in "iu" and dt.itemsize <= 4:
        return array if dt.isnative else array.astype(dt.newbyteorder("="))
    if dt.kind == "f" and array.size and not np.array_equal(array, np.floor(array)):
        bad = np.argwhere(~(array == np.floor(array)))[0]
        raise ValueError("labels: a label map holds integers; this one has %r at index %s"
                         % (array[tuple(bad)].item(), tuple(int(i) for i in bad)))
    lo, hi = (int(array.min()), int(array.max())) if array.size else (0, 0)
    if lo >= 0 and hi <= 0xFFFFFFFF:
        return array.astype(np.uint32)
    if lo >= -2**31 and hi < 2**31:
        return array.astype(np.int32)
    raise ValueError("labels: values %d..%d do not fit a 32-bit integer type" % (lo, hi))


def _as_volume(array, axes, spacing, origin, slice_positions=None, label_map=False):
    """Describes a numpy array as an isomend_volume without copying when possible.
    Returns (Volume, the arrays kept alive: the samples and the slice origins).
    ``slice_positions``: the z of each slice (one per slice along world z), for
    slices that are not evenly spaced: slice k's sample (0, 0) is at (origin x,
    origin y, slice_positions[k]) (isomend_volume.slice_origins)."""
    if not isinstance(array, np.ndarray):
        array = np.asarray(array)
    if array.ndim != 3:
        raise ValueError("volume: expected a 3D array, got shape %s" % (array.shape,))
    if label_map:
        array = _label_array(array)
    elif array.dtype == np.bool_:
        array = array.view(np.uint8)
    elif array.dtype == np.float16:
        array = array.astype(np.float32)
    elif array.dtype in (np.dtype(np.uint32), np.dtype(np.int64), np.dtype(np.uint64)):
        array = array.astype(np.float64)
    if array.dtype.kind in "iuf" and not array.dtype.isnative:
        array = array.astype(array.dtype.newbyteorder("="))
    vtype = (_LABEL_DTYPE_TO_TYPE if label_map else _DTYPE_TO_TYPE).get(np.dtype(array.dtype))
    if vtype is None:
        raise TypeError("volume: unsupported dtype %s (use uint8, int8, uint16, int16, int32, "
                        "float32 or float64)" % array.dtype)
    axes = axes.lower()
    if sorted(axes) != ["x", "y", "z"]:
        raise ValueError("axes: expected a permutation of 'xyz' naming the array's axes, got %r" % axes)
    vol = Volume()
    vol.data = array.ctypes.data
    vol.type = vtype
    for array_axis, name in enumerate(axes):
        world = "xyz".index(name)
        vol.dims[world] = array.shape[array_axis]
        vol.strides[world] = array.strides[array_axis]
    if all(vol.strides[i] == 0 for i in range(3)):
        # The C API reads all-zero strides as "contiguous": only possible here for a
        # fully broadcast array, whose samples are all equal; make it explicit.
        array = np.ascontiguousarray(array)
        return _as_volume(array, axes, spacing, origin, slice_positions, label_map)
    sp = _triple(spacing, "spacing", 1.0)
    for i, s in enumerate(sp):
        if not (math.isfinite(s) and s > 0):
            raise ValueError("spacing: %s component must be finite and > 0, got %r" % ("xyz"[i], s))
    org = _triple(origin, "origin", 0.0)
    for i, o in enumerate(org):
        if not math.isfinite(o):
            raise ValueError("origin: %s component must be finite, got %r" % ("xyz"[i], o))
    vol.spacing[:] = sp
    vol.origin[:] = org
    table = None
    if slice_positions is not None:
        z = _slice_positions(slice_positions, "slice_positions", vol.dims[2])
        table = np.empty((len(z), 3), np.float64)  # C order: x, y, z of each slice
        table[:, 0], table[:, 1], table[:, 2] = org[0], org[1], z
        vol.slice_origins = table.ctypes.data
    return vol, (array, table)


def _triple(value, name, default):
    if value is None:
        return (default, default, default)
    if np.isscalar(value):
        return (float(value),) * 3
    vals = tuple(float(v) for v in value)
    if len(vals) != 3:
        raise ValueError("%s: expected 3 numbers (x, y, z) or one, got %d" % (name, len(vals)))
    return vals


def _options(iso, method, pad, flip, normals, origins, threads, progress, small_pages=False):
    opts = Options()
    _core_lib().isomend_options_init(ctypes.byref(opts))
    if iso is not None:
        iso = float(iso)
        if not math.isfinite(iso):
            raise ValueError("iso: must be finite, got %r" % iso)
        opts.iso = iso
    opts.method = _method_id(method)
    flags = 0
    if pad:
        flags |= FLAG_PAD
    if flip:
        flags |= FLAG_FLIP
    if not normals:
        flags |= FLAG_NO_NORMALS
    if not origins:
        flags |= FLAG_NO_ORIGINS
    if small_pages:
        flags |= FLAG_SMALL_PAGES
    opts.flags = flags
    if threads is None:
        threads = 0
    threads = int(threads)
    if threads < 0:
        raise ValueError("threads: must be >= 0 (0 = all cores), got %d" % threads)
    opts.threads = threads
    if progress is not None:
        opts.progress = progress.c_fn
    return opts


# ------------------------------------------------------------ meshes

def _stats_dict(st):
    return {
        "cubes": st.cubes,
        "case_histogram": list(st.case_histogram),
        "ambiguous_faces": st.ambiguous_faces,
        "inverted_combinations": st.inverted_combinations,
        "triangles_by_origin": dict(zip(ORIGIN_NAMES, st.triangles_by_origin)),
        "mending_triangles": st.triangles_by_origin[ORIGIN_MEND],
        "durst_triangles": st.triangles_by_origin[ORIGIN_DURST],
        "nan_samples": st.nan_samples,
        "vertices": st.vertices,
        "triangles": st.triangles,
    }


def _report_dict(rep):
    return {name: getattr(rep, name) for name, _ in CheckReport._fields_}


def _struct_dict(rep):
    return {name: getattr(rep, name) for name, _ in type(rep)._fields_}


def _count(value, name):
    """A non-negative integer argument (bool refused)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError("%s: an integer, not %r" % (name, value))
    if value < 0:
        raise ValueError("%s: %d is negative" % (name, value))
    return int(value)


def _decimate_targets(ratio=None, target_triangles=None, max_error=None):
    """The decimation targets checked (no library needed): (ratio or 0,
    target_triangles or 0, max_error or 0)."""
    if ratio is None and target_triangles is None and max_error is None:
        raise ValueError("decimate: give ratio, target_triangles or max_error")
    r = t = e = 0
    if ratio is not None:
        r = float(ratio)
        if not (0.0 < r <= 1.0):
            raise ValueError("ratio: %r is not a fraction of the triangles to keep, in (0, 1]" % ratio)
    if target_triangles is not None:
        t = _count(target_triangles, "target_triangles")
        if t == 0:
            raise ValueError("target_triangles: 0 (give a count > 0, or None)")
    if max_error is not None:
        e = float(max_error)
        if not (np.isfinite(e) and e > 0.0):
            raise ValueError("max_error: %r is not a distance > 0" % max_error)
    return r, t, e


def _decimate_options(ratio, target_triangles, max_error):
    r, t, e = _decimate_targets(ratio, target_triangles, max_error)
    opts = DecimateOptions()
    _core_lib().isomend_decimate_options_init(ctypes.byref(opts))
    opts.ratio, opts.target_triangles, opts.max_error = r, t, e
    return opts


def postprocess(mesh, decimate=None, smooth=0, min_component=0, largest=0):
    """The command line's post-processing of an extracted Mesh, in its order:
    clean-up (``min_component``: drop components of fewer triangles;
    ``largest``: keep the N largest), smoothing (``smooth`` iterations),
    decimation (``decimate``: a ratio in (0, 1], or a dict with ratio,
    target_triangles, max_error).  0/None skip a step.  Returns the last
    Mesh made (``mesh`` itself when no step runs); its ``postprocess`` dict
    holds each step's report."""
    min_component, largest, smooth, targets = check_postprocess(decimate, smooth, min_component,
                                                                 largest)
    if min_component or largest:
        mesh, _ = mesh.clean(min_component, largest)
    if smooth:
        mesh, _ = mesh.smooth(smooth)
    if targets is not None:
        mesh, _ = mesh.decimate(**targets)
    return mesh


def check_postprocess(decimate=None, smooth=0, min_component=0, largest=0):
    """Checks postprocess()'s arguments without a mesh (before an
    extraction): returns (min_component, largest, smooth, decimation targets
    as a dict or None), raises ValueError/TypeError."""
    min_component = _count(min_component, "min_component")
    largest = _count(largest, "largest")
    smooth = _count(smooth, "smooth")
    if isinstance(decimate, dict):
        unknown = set(decimate) - {"ratio", "target_triangles", "max_error"}
        if unknown:
            raise ValueError("decimate: unknown keys %s" % sorted(unknown))
        targets = dict(decimate)
    elif decimate is not None and not (isinstance(decimate, (int, float)) and decimate == 0):
        targets = {"ratio": decimate}
    else:
        targets = None
    if targets is not None:
        _decimate_targets(**targets)  # refused before any step runs
    if smooth > 10000:
        raise ValueError("smooth: %d is more than 10000" % smooth)
    return min_component, largest, smooth, targets


class Mesh:
    """An extracted mesh held in numpy arrays (views of the C mesh's own arrays,
    which is freed when the last of them is released).

    positions (V, 3) float32; normals (V, 3) float32 or None; triangles (T, 3)
    uint32; origins (T,) uint8 or None (ORIGIN_TABLE/DURST/MEND); grid_box
    (min x, y, z, max x, y, z) of the sampled grid (padded if pad=True); stats
    dict; iso and method used; volume_origin and volume_spacing (x, y, z) of
    the volume as extracted (the world position of its sample (0, 0, 0): from
    Source.extract it may differ from Source.origin for a file whose axis
    points the negative way); read_seconds (Source.extract only).

    Post-processing (the core's, each keeping a closed, oriented surface
    closed): ``clean()``, ``smooth()`` and ``decimate()`` return a new Mesh and
    the step's report as a dict; the new mesh's ``stats`` stay the
    extraction's, its ``origins`` are None and its ``postprocess`` dict holds
    the reports of every step that made it ("clean", "smooth", "decimate";
    None for a step not run), as the command line's --json.
    """

    def __init__(self, positions, normals, triangles, origins, grid_box, stats, iso, method):
        self.positions = positions
        self.normals = normals
        self.triangles = triangles
        self.origins = origins
        self.grid_box = grid_box
        self.stats = stats
        self.iso = iso
        self.method = method
        # the volume's sample (0, 0, 0) in world units and its spacing
        self.volume_origin = None
        self.volume_spacing = None
        self.read_seconds = None
        self.postprocess = {"clean": None, "smooth": None, "decimate": None}
        self._c = None      # the C mesh (_MeshMemory) the arrays come from
        self._world = None  # the 3x4 map of a mesh copied into patient space

    def _derived(self, handle, step, report):
        """The Mesh of a post-processing step's C mesh ``handle``."""
        lib = _core_lib()
        mesh = _wrap_mesh(lib, handle, dict(self.stats), self.iso, self.method,
                          self.normals is not None, False, self._world)
        mesh.volume_origin = self.volume_origin
        mesh.volume_spacing = self.volume_spacing
        mesh.read_seconds = self.read_seconds
        mesh.postprocess = dict(self.postprocess)
        mesh.postprocess[step] = report
        return mesh

    def _handle(self, what):
        if self._c is None or self._c._handle is None:
            raise ValueError("%s: this Mesh was not made by isomend (no C mesh to work on)" % what)
        return self._c._handle

    def clean(self, min_triangles=0, keep_largest=0):
        """Drops the connected components (triangles joined through shared
        vertices) of fewer than ``min_triangles`` triangles, then keeps the
        ``keep_largest`` largest (0: all).  Returns (Mesh, report) with report
        keys components_before, components_after, triangles_removed,
        vertices_removed (isomend_mesh_clean)."""
        min_triangles = _count(min_triangles, "min_triangles")
        keep_largest = _count(keep_largest, "keep_largest")
        lib = _core_lib()
        out, rep = ctypes.c_void_p(), CleanReport()
        status = lib.isomend_mesh_clean(self._handle("clean"), min_triangles, keep_largest,
                                        ctypes.byref(out), ctypes.byref(rep))
        if status != 0:
            if out.value:
                lib.isomend_mesh_destroy(out)
            _raise_core(status, "isomend_mesh_clean")
        report = _struct_dict(rep)
        return self._derived(out, "clean", report), report

    def smooth(self, iterations):
        """Windowed sinc smoothing (VTK's and 3D Slicer's filter), ``iterations``
        umbrella steps (0..10000), then each component's enclosed volume restored; locked vertices (on a
        border or a hole) never move.  Returns (Mesh, report) with report keys
        moved_vertices, volume_before, volume_after, max_displacement
        (isomend_mesh_smooth)."""
        iterations = _count(iterations, "iterations")
        if iterations > 10000:
            raise ValueError("iterations: %d is more than 10000" % iterations)
        lib = _core_lib()
        out, rep = ctypes.c_void_p(), SmoothReport()
        status = lib.isomend_mesh_smooth(self._handle("smooth"), iterations, ctypes.byref(out),
                                         ctypes.byref(rep))
        if status != 0:
            if out.value:
                lib.isomend_mesh_destroy(out)
            _raise_core(status, "isomend_mesh_smooth")
        report = _struct_dict(rep)
        return self._derived(out, "smooth", report), report

    def decimate(self, ratio=None, target_triangles=None, max_error=None):
        """Quadric-error edge collapse that keeps the surface closed and
        2-manifold.  Targets (at least one): ``ratio`` the fraction of the
        triangles to keep, in (0, 1]; ``target_triangles`` a count (the larger
        of the two is kept); ``max_error`` a distance in world units every
        input vertex stays within.  Returns (Mesh, report) with report keys
        triangles_before/after, vertices_before/after, target_triangles,
        reached (bool: False when every further collapse would break the
        surface or exceed max_error), max_error and mean_error (measured),
        collapses, locked_vertices, refused_topology, refused_geometry,
        refused_error (isomend_mesh_decimate)."""
        opts = _decimate_options(ratio, target_triangles, max_error)
        lib = _core_lib()
        out, rep = ctypes.c_void_p(), DecimateReport()
        status = lib.isomend_mesh_decimate(self._handle("decimate"), ctypes.byref(opts),
                                           ctypes.byref(out), ctypes.byref(rep))
        if status != 0:
            if out.value:
                lib.isomend_mesh_destroy(out)
            _raise_core(status, "isomend_mesh_decimate")
        report = _struct_dict(rep)
        report["reached"] = bool(report["reached"])
        return self._derived(out, "decimate", report), report

    @property
    def vertex_count(self):
        return len(self.positions)

    @property
    def triangle_count(self):
        return len(self.triangles)

    def check(self):
        """Runs the continuity checker against the grid box: a dict with
        hole_edges, nonmanifold_edges, misoriented_edges, border_edges, ...,
        euler (V - E + F)."""
        return check(self.positions, self.triangles, box=self.grid_box)

    def __repr__(self):
        return "<isomend.Mesh %s iso=%g: %d vertices, %d triangles (%d mending)>" % (
            self.method, self.iso, self.vertex_count, self.triangle_count,
            self.stats.get("mending_triangles", 0))


_F32, _U32, _U8 = (np.dtype(t).str for t in (np.float32, np.uint32, np.uint8))  # native order


class _MeshMemory:
    """Owns a C mesh whose arrays numpy views: destroys it when the last view goes."""

    def __init__(self, handle):
        self._handle = handle

    def view(self, pointer, shape, typestr):
        """A writable numpy array over ``shape`` items of C memory, keeping self alive."""
        if not pointer or 0 in shape:
            return np.empty(shape, np.dtype(typestr))
        return np.asarray(_ArrayView(self, ctypes.cast(pointer, ctypes.c_void_p).value,
                                     shape, typestr))

    def __del__(self):
        handle, self._handle = self._handle, None
        lib = _core
        if handle is not None and lib is not None:
            lib.isomend_mesh_destroy(handle)


class _ArrayView:
    """The numpy array interface of one of a mesh's arrays (becomes the array's base)."""

    def __init__(self, owner, address, shape, typestr):
        self._owner = owner
        self.__array_interface__ = {"data": (address, False), "shape": tuple(shape),
                                    "typestr": typestr, "version": 3}


def _take_mesh(handle, stats, iso, method_id, want_normals, want_origins, world=None):
    """Wraps a C mesh's arrays in numpy arrays without copying them: the C mesh
    lives until the last of those arrays is released.  A mesh of 15 M triangles
    is 350 MB; a copy would double the peak memory and cost as much time as a
    third of the extraction.  ``world`` (3x4, a DICOM series' patient
    transform) instead copies the mesh through the map
    (isomend_mesh_copy_transformed)."""
    lib = _core_lib()
    name = lib.isomend_method_name(method_id).decode()
    return _wrap_mesh(lib, handle, _stats_dict(stats), iso, name, want_normals, want_origins, world)


def _wrap_mesh(lib, handle, stats, iso, method_name, want_normals, want_origins, world):
    """A Mesh over the C mesh ``handle`` (owned from now on: destroyed with
    the Mesh's last array, or at once if this fails).  The Mesh keeps the C
    mesh (``_c``) for the post-processing methods, which work on it; with
    ``world`` its arrays are a mapped copy and ``_world`` the map."""
    owner = _MeshMemory(handle)  # destroys the handle if anything below fails
    nv = lib.isomend_mesh_vertex_count(handle)
    nt = lib.isomend_mesh_triangle_count(handle)
    box = (ctypes.c_double * 6)()
    lib.isomend_mesh_grid_box(handle, box)
    if world is None:
        positions = owner.view(lib.isomend_mesh_positions(handle), (nv, 3), _F32)
        triangles = owner.view(lib.isomend_mesh_triangles(handle), (nt, 3), _U32)
        normals = (owner.view(lib.isomend_mesh_normals(handle), (nv, 3), _F32)
                   if want_normals else None)
        origins = (owner.view(lib.isomend_mesh_triangle_origins(handle), (nt,), _U8)
                   if want_origins else None)
        grid_box = tuple(box)
    else:
        positions = np.empty((nv, 3), np.float32)
        triangles = np.empty((nt, 3), np.uint32)
        normals = np.empty((nv, 3), np.float32) if want_normals else None
        origins = np.empty((nt,), np.uint8) if want_origins else None
        A = (ctypes.c_double * 12)(*[float(v) for v in np.asarray(world, float).reshape(-1)])
        ptr = lambda a: a.ctypes.data if a is not None and a.size else None
        status = lib.isomend_mesh_copy_transformed(handle, A, ptr(positions), ptr(normals),
                                                   ptr(triangles), ptr(origins))
        if status != 0:
            _raise_core(status, "isomend_mesh_copy_transformed")
        # the box of the mapped grid's corners (a turned grid's faces are not the
        # box's: check() then sees its border as holes unless the mesh is padded)
        M = np.asarray(world, float).reshape(3, 4)
        corners = np.array([[box[a], box[1 + b], box[2 + c]] for a in (0, 3) for b in (0, 3)
                            for c in (0, 3)], float)
        mapped = corners @ M[:, :3].T + M[:, 3]
        grid_box = tuple(mapped.min(0).tolist() + mapped.max(0).tolist())
    mesh = Mesh(positions, normals, triangles, origins, grid_box, stats, iso, method_name)
    mesh._c = owner
    mesh._world = world
    return mesh


def extract(volume, iso, method="dmc", spacing=None, origin=None, pad=False, flip=False,
            normals=True, origins=True, threads=0, axes="zyx", progress=None,
            small_pages=False, slice_positions=None, decimate=None, smooth=0, min_component=0,
            largest=0):
    """Extracts the isosurface of a 3D numpy array at level ``iso``.

    volume:  3D array, ``array[z, y, x]`` unless ``axes`` says otherwise (see the module doc).
    iso:     finite level; a sample >= iso is inside.
    method:  "dmc" (default, the thesis's mended MC), "mc", "durst", ... or an id.
    spacing: (x, y, z) world distance between samples, or one number (default 1).
    origin:  (x, y, z) world position of sample (0, 0, 0) (default 0).
    pad:     surround with an outside layer: closed surfaces.
    flip:    normals towards higher values, winding reversed to match.
    normals: compute gradient normals (else mesh.normals is None).
    origins: record each triangle's origin (else mesh.origins is None).
    threads: worker threads, 0 = all cores (the mesh does not depend on it).
    progress: callable(stage, fraction) -> True to cancel.
    small_pages: output arrays without huge pages (ISOMEND_FLAG_SMALL_PAGES); the same
             mesh.  Huge pages, the default, were faster on every machine measured but
             one virtual machine, for a process that extracts once (see the README).
    slice_positions: for slices that are not evenly spaced, the world z of each slice
             (one per slice along z, finite, strictly increasing): slice k is meshed at
             z = slice_positions[k], its sample (0, 0) at (origin x, origin y); spacing z
             and origin z are then not used (isomend_volume.slice_origins).
    min_component, largest, smooth, decimate: post-processing, in the command line's
             order (see postprocess()): drop components of fewer than min_component
             triangles, keep the `largest` largest, `smooth` windowed sinc iterations, then
             decimate (a ratio in (0, 1], or a dict of ratio, target_triangles,
             max_error).  0/None: off.  The reports are in mesh.postprocess.
    Returns a Mesh.  Raises IsomendError (Cancelled when cancelled), ValueError, TypeError.
    """
    if iso is None:
        raise ValueError("iso: required for a numpy volume (a Source can suggest one)")
    post = {"decimate": decimate, "smooth": smooth, "min_component": min_component,
            "largest": largest}
    if decimate is not None or smooth or min_component or largest:
        # the arguments are checked before the extraction
        check_postprocess(**post)
    vol, keep = _as_volume(volume, axes, spacing, origin, slice_positions)
    prog = _Progress(progress) if progress is not None else None
    opts = _options(iso, method, pad, flip, normals, origins, threads, prog, small_pages)
    handle = ctypes.c_void_p()
    stats = Stats()
    status = _core_lib().isomend_extract(ctypes.byref(vol), ctypes.byref(opts),
                                         ctypes.byref(handle), ctypes.byref(stats))
    first_slice = keep[1][0].tolist() if keep[1] is not None else None
    del keep
    if prog is not None:
        prog.reraise()
    if status != 0:
        if handle.value:
            _core_lib().isomend_mesh_destroy(handle)
        _raise_core(status, "isomend_extract")
    mesh = _take_mesh(handle, stats, opts.iso, opts.method, normals, origins)
    # sample (0, 0, 0): on the first slice when the slices are placed one by one
    mesh.volume_origin = tuple(first_slice) if first_slice else tuple(vol.origin)
    mesh.volume_spacing = tuple(vol.spacing)
    return postprocess(mesh, **post)


class _Closable:
    """with-statement and garbage collection both call close()."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass


# ------------------------------------------------------------ label maps

class _LabelNames(_Closable):
    """An isomend_io_label_names set (or none: every label is label_N with
    the palette's colour).  name(value) -> (name, (r, g, b), known)."""

    def __init__(self, lib, handle=None):
        self._lib = lib
        self._handle = handle if handle is not None and handle.value else None
        raw = lib.isomend_io_label_names_from(self._handle) if lib is not None else None
        self.names_from = raw.decode() if raw else None

    def name(self, value):
        if self._lib is None:  # no importer library: the names the core's own values give
            return "label_%d" % value, None, False
        buf = ctypes.create_string_buffer(256)
        rgb = (ctypes.c_uint8 * 3)()
        known = self._lib.isomend_io_label_name(self._handle, int(value), buf, len(buf), rgb)
        return buf.value.decode(errors="replace"), tuple(rgb), bool(known)

    def close(self):
        handle, self._handle = self._handle, None
        if handle is not None:
            self._lib.isomend_io_label_names_destroy(handle)


def _labels_argument(labels):
    """(ctypes int64 array or None, count) of a labels argument: "all"/None
    (every label present but 0), an integer, an iterable of integers, or a
    string "L1,L2,..."; distinct values."""
    if labels is None or (isinstance(labels, str) and labels.strip().lower() == "all"):
        return None, 0
    if isinstance(labels, str):
        try:
            values = [int(t) for t in labels.split(",")]
        except ValueError:
            raise ValueError("labels: %r is not 'all' or integers L1,L2,..." % labels) from None
    elif isinstance(labels, (int, np.integer)) and not isinstance(labels, bool):
        values = [int(labels)]
    else:
        values = []
        for v in labels:
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise TypeError("labels: %r is not an integer label" % (v,))
            values.append(int(v))
    if not values:
        raise ValueError("labels: no label given (use 'all', or a list of labels)")
    seen = set()
    for v in values:
        if v in seen:
            raise ValueError("labels: label %d is listed twice" % v)
        if not -2**63 <= v < 2**63:
            raise ValueError("labels: %d is out of the 64-bit range" % v)
        seen.add(v)
    return (ctypes.c_int64 * len(values))(*values), len(values)


_LABEL_METHODS = ("dmc", "mc", "durst")


def _label_options(method, pad, flip, normals, origins, threads, progress):
    opts = _options(None, method, pad, flip, normals, origins, threads, progress)
    name = _core_lib().isomend_method_name(opts.method).decode()
    if name not in _LABEL_METHODS:
        raise IsomendError("method: a label map takes dmc (the default), mc or durst, not %r"
                           % name, 9, "UNSUPPORTED")
    return opts


def _label_meshes(result, method_id, normals, origins, world, names):
    """{value: Mesh} of an isomend_labels result (destroyed here), each Mesh
    owning its C mesh (isomend_labels_take_mesh), with label, voxels, name,
    color (r, g, b, 0..255) and names_from."""
    lib = _core_lib()
    try:
        return _take_label_meshes(lib, result, method_id, normals, origins, world, names)
    finally:
        lib.isomend_labels_destroy(result)


def _take_label_meshes(lib, result, method_id, normals, origins, world, names):
    method_name = lib.isomend_method_name(method_id).decode()
    out = {}
    for q in range(lib.isomend_labels_count(result)):
        value = int(lib.isomend_labels_value(result, q))
        handle = ctypes.c_void_p(lib.isomend_labels_take_mesh(result, q))
        stats = {"vertices": lib.isomend_mesh_vertex_count(handle),
                 "triangles": lib.isomend_mesh_triangle_count(handle),
                 "voxels": int(lib.isomend_labels_voxels(result, q))}
        mesh = _wrap_mesh(lib, handle, stats, 0.5, method_name, normals, origins, world)
        if mesh.origins is not None:
            by = np.bincount(mesh.origins, minlength=3)[:3].tolist()
            stats["triangles_by_origin"] = dict(zip(ORIGIN_NAMES, by))
            stats["durst_triangles"], stats["mending_triangles"] = by[ORIGIN_DURST], by[ORIGIN_MEND]
        mesh.label = value
        mesh.voxels = stats["voxels"]
        mesh.name, mesh.color, _ = names.name(value)
        mesh.names_from = names.names_from
        out[value] = mesh
    return out


def _labels_step(meshes, step, call, report_type):
    """{value: Mesh} of a step on a label map's meshes together; the C call
    `call(handles, n, outs, reports)`; (meshes, {value: report})."""
    values = list(meshes)
    n = len(values)
    lib = _core_lib()
    handles = (ctypes.c_void_p * max(n, 1))(*[meshes[k]._handle(step) for k in values])
    outs = (ctypes.c_void_p * max(n, 1))()
    reps = (report_type * max(n, 1))()
    status = call(lib, handles, n, outs, reps)
    if status != 0:
        for q in range(n):
            if outs[q]:
                lib.isomend_mesh_destroy(ctypes.c_void_p(outs[q]))
        _raise_core(status, "isomend_meshes_" + step)
    out, reports = {}, {}
    for q, value in enumerate(values):
        rep = _struct_dict(reps[q])
        if "reached" in rep:
            rep["reached"] = bool(rep["reached"])
        m = meshes[value]._derived(ctypes.c_void_p(outs[q]), step, rep)
        for attr in ("label", "voxels", "name", "color", "names_from"):
            setattr(m, attr, getattr(meshes[value], attr, None))
        out[value], reports[value] = m, rep
    return out, reports


def smooth_labels(meshes, iterations):
    """A label map's meshes ({value: Mesh}, as extract_labels() gives them)
    smoothed together (isomend_meshes_smooth): the windowed sinc filter of
    Mesh.smooth(), a vertex two labels share moved once, so neighbouring
    surfaces still meet exactly; no volume restored.  Returns ({value: Mesh},
    {value: report}) with Mesh.smooth()'s report keys."""
    iterations = _count(iterations, "iterations")
    if iterations > 10000:
        raise ValueError("iterations: %d is more than 10000" % iterations)
    return _labels_step(meshes, "smooth",
                        lambda lib, h, n, o, r: lib.isomend_meshes_smooth(h, n, iterations, o, r),
                        SmoothReport)


def decimate_labels(meshes, ratio=None, target_triangles=None, max_error=None):
    """A label map's meshes ({value: Mesh}) decimated together
    (isomend_meshes_decimate): the vertices another label holds too stay, so
    the surfaces two labels share stay in both; the rest of each mesh as
    Mesh.decimate() with these targets (a label each).  Returns ({value:
    Mesh}, {value: report})."""
    opts = _decimate_options(ratio, target_triangles, max_error)
    return _labels_step(meshes, "decimate",
                        lambda lib, h, n, o, r: lib.isomend_meshes_decimate(h, n, ctypes.byref(opts),
                                                                            o, r),
                        DecimateReport)


def _names_of_table(label_table):
    """_LabelNames of a colour table file (None: none), through the importer."""
    try:
        lib = _io_lib()
    except LibraryNotFound:
        if label_table is not None:
            raise
        return _LabelNames(None)
    if label_table is None:
        return _LabelNames(lib)
    handle = ctypes.c_void_p()
    status = lib.isomend_io_create(ctypes.byref(handle))
    if status != 0 or not handle.value:
        raise IsomendError("isomend_io_create: out of memory", status or 9,
                           IO_STATUS_NAMES.get(status or 9, "?"))
    with Source._adopt(lib, handle, []) as src:  # which frees the handle
        names = ctypes.c_void_p()
        status = lib.isomend_io_label_names_read(handle, os.fsencode(label_table), ctypes.byref(names))
        if status != 0:
            src._raise(status, "label_table")
        return _LabelNames(lib, names)


def extract_labels(volume, labels=None, method="dmc", spacing=None, origin=None, pad=True,
                   flip=False, normals=True, origins=True, threads=0, axes="zyx", progress=None,
                   label_table=None):
    """The surface of each label of a label map (a segmentation), all labels in
    one pass over the volume (isomend_labels_extract).

    volume:  3D integer array (uint8, int8, uint16, int16, int32, uint32 read in
             place; bool as uint8; int64/uint64 and floats whose values are all
             whole numbers copied as uint32 or int32 when they fit 32 bits; a
             fraction or NaN is refused), axes as for extract().
    labels:  None or "all" (every value present but 0, the background), an
             integer, a list of distinct integers, or "L1,L2,...".
    method:  "dmc" (default: with pad, the default here, each label a closed
             oriented 2-manifold), "mc" or "durst".
    label_table: a colour table file (3D Slicer .ctbl/.txt, FreeSurfer's LUT,
             ITK-SNAP's label description) for the names and colours; else
             label_N and a fixed palette.
    spacing, origin, pad, flip, normals, origins, threads, progress: as extract().

    Label L's surface is its indicator's (voxel == L) at 0.5: the same mesh as
    extract((volume == L).astype(numpy.uint8), 0.5, ...) byte for byte; where
    two labels touch their surfaces share the boundary's vertex positions.
    Returns {value: Mesh} in label order; each Mesh has ``label``, ``name``,
    ``color`` ((r, g, b) 0..255), ``voxels`` and ``names_from`` besides
    extract()'s attributes (its ``stats``: vertices, triangles, voxels,
    triangles_by_origin).  Raises IsomendError for a label not in the volume
    (as the command line and the hosts refuse it), for none but 0 and for a
    method labels do not take, TypeError/ValueError for bad arguments."""
    values, count = _labels_argument(labels)
    vol, keep = _as_volume(volume, axes, spacing, origin, label_map=True)
    prog = _Progress(progress) if progress is not None else None
    opts = _label_options(method, pad, flip, normals, origins, threads, prog)
    names = _names_of_table(label_table)  # a bad table is refused before any work
    with names:
        result = ctypes.c_void_p()
        lib = _core_lib()
        status = lib.isomend_labels_extract(ctypes.byref(vol), values, count, ctypes.byref(opts),
                                            ctypes.byref(result))
        del keep
        if prog is not None:
            prog.reraise()
        if status != 0:
            if result.value:
                lib.isomend_labels_destroy(result)
            _raise_core(status, "isomend_labels_extract")
        meshes = _label_meshes(result, opts.method, normals, origins, None, names)
    if not meshes:
        raise IsomendError("labels: the volume has no label but the background 0", 1,
                           "INVALID_ARGUMENT")
    for mesh in meshes.values():
        if mesh.voxels == 0:
            raise IsomendError("labels: label %d is not in the volume" % mesh.label, 1,
                               "INVALID_ARGUMENT")
        mesh.volume_origin = tuple(vol.origin)
        mesh.volume_spacing = tuple(vol.spacing)
    return meshes


def check(positions, triangles, box=None):
    """Continuity check of any triangle mesh: positions (V, 3) float, triangles
    (T, 3) int.  ``box`` (min x, y, z, max x, y, z) is the volume's box: once-used
    edges in its faces are border edges, others hole edges (None: the mesh's own
    bounding box).  Returns a dict (see CheckReport)."""
    pos = np.ascontiguousarray(positions, dtype=np.float32)
    tri = np.asarray(triangles)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise ValueError("positions: expected shape (V, 3), got %s" % (pos.shape,))
    if tri.ndim != 2 or tri.shape[1] != 3:
        raise ValueError("triangles: expected shape (T, 3), got %s" % (tri.shape,))
    if tri.size and (tri.min() < 0 or tri.max() >= len(pos)):
        raise ValueError("triangles: index out of range 0..%d" % (len(pos) - 1))
    tri = np.ascontiguousarray(tri, dtype=np.uint32)
    cbox = None
    if box is not None:
        b = [float(v) for v in box]
        if len(b) != 6:
            raise ValueError("box: expected 6 numbers (min x, y, z, max x, y, z)")
        cbox = (ctypes.c_double * 6)(*b)
    rep = CheckReport()
    status = _core_lib().isomend_check(pos.ctypes.data, len(pos), tri.ctypes.data, len(tri),
                                       cbox, ctypes.byref(rep))
    if status != 0:
        _raise_core(status, "isomend_check")
    return _report_dict(rep)


# ------------------------------------------------------------ slice sources

def _paths_list(paths):
    if isinstance(paths, (str, bytes, os.PathLike)):
        paths = [paths]
    out = []
    for p in paths:
        p = os.fsencode(p)
        if not p:
            raise ValueError("paths: empty path")
        out.append(p)
    if not out:
        raise ValueError("paths: no path given")
    return out


def _io_options(lib, channel=None, spacing=None, origin=None, first=0, count=0, step=1,
                threads=0, memory_limit=0, raw_dims=None, raw_type=None, raw_header=0,
                raw_big_endian=False, slice_positions=None):
    """isomend_io_options from open_source()'s keyword arguments (checked), no progress.
    The slice positions' array is kept alive by the returned struct (``_keep``)."""
    opts = IOOptions()
    lib.isomend_io_options_init(ctypes.byref(opts))
    opts.first, opts.count, opts.step = int(first), int(count), int(step)
    if channel is not None:
        if isinstance(channel, str):
            names = {"auto": IO_CHANNEL_AUTO, "luma": IO_CHANNEL_LUMA}
            if channel.lower() not in names:
                raise ValueError("channel: expected an index >= 0, 'auto' or 'luma', got %r" % channel)
            channel = names[channel.lower()]
        channel = int(channel)
        if channel < IO_CHANNEL_LUMA:
            raise ValueError("channel: expected an index >= 0, -1 (auto) or -2 (luma), got %d" % channel)
        opts.channel = channel
    if spacing is not None:
        sp = _triple(spacing, "spacing", 1.0)
        for i, s in enumerate(sp):
            if not (math.isfinite(s) and s > 0):
                raise ValueError("spacing: %s component must be finite and > 0, got %r" % ("xyz"[i], s))
        opts.spacing[:] = sp
    if origin is not None:
        org = _triple(origin, "origin", 0.0)
        if not all(math.isfinite(o) for o in org):
            raise ValueError("origin: components must be finite, got %r" % (org,))
        opts.origin[:] = org
    if int(threads) < 0:
        raise ValueError("threads: must be >= 0 (0 = one per core)")
    opts.threads = int(threads)
    opts.memory_limit = int(memory_limit)
    if raw_dims is not None:
        dims = [int(d) for d in raw_dims]
        if len(dims) != 3 or min(dims) <= 0:
            raise ValueError("raw_dims: expected 3 sizes > 0 (nx, ny, nz), got %r" % (raw_dims,))
        opts.raw_dims[:] = dims
        if raw_type is None:
            raise ValueError("raw_type: required with raw_dims (e.g. 'u16' or numpy.uint16)")
        opts.raw_type = _type_id(raw_type)
    opts.raw_header = int(raw_header)
    opts.raw_big_endian = 1 if raw_big_endian else 0
    if slice_positions is not None:
        z = np.ascontiguousarray(_slice_positions(slice_positions, "slice_positions"))
        opts.slice_positions = z.ctypes.data
        opts.slice_position_count = len(z)
        opts._keep = z  # read by isomend_io_open (a job's: on its thread, later)
    return opts


def _dicom_choices(lib, handle, series, grid_axes):
    """isomend_io_set_series / _set_axes on a handle before it is opened."""
    if series is not None:
        text = str(series).strip()
        if not text:
            raise ValueError("series: empty (a 1-based position or a Series Instance UID)")
        if lib.isomend_io_set_series(handle, text.encode()) != 0:
            raise ValueError("series: %r refused" % (series,))
    if grid_axes:
        lib.isomend_io_set_axes(handle, IO_AXES_GRID)


class Source(_Closable):
    """An opened, validated slice stack / raw / NRRD source (wraps isomend_io_source).

    Use as a context manager or call close(); the handle is also released when
    the object is garbage-collected.  Attributes after opening: dims (nx, ny,
    nz), dtype, spacing (x, y, z), spacing_sources, origin, kind, format,
    volume_bytes, slice_bytes; for a DICOM series also ``dicom`` (a dict:
    modality, series_uid, description, rescale, orientation, ...), ``series``
    (every series found) and ``world_transform`` (the 3x4 patient transform
    of the mesh, None when it is the identity), else None / [] / None.
    Every source has ``geometry`` (a dict: uniform, gap_median, gap_min,
    gap_max, tilt_degrees, max_offset, long_gaps, uneven_gaps, warning: ""
    or one line for the user) and ``slice_origins``: None for evenly spaced
    slices, else an (nz, 3) array, each slice's sample (0, 0) in the frame of
    the loaded volume (the mesh is built at these positions).
    ``slice_positions`` (the z of each slice of a stack, raw or NRRD volume
    whose slices are not evenly spaced) places them; a DICOM series has its own.

    DICOM: ``series`` picks one (a Series Instance UID, or its 1-based
    position N as listed); ``grid_axes=True`` keeps the series' own axes.  A
    folder of several series without a choice raises IsomendError with
    status_name "SERIES" and the list in its message and ``.series``.
    """

    def __init__(self, paths, channel=None, spacing=None, origin=None, first=0, count=0, step=1,
                 threads=0, memory_limit=0, raw_dims=None, raw_type=None, raw_header=0,
                 raw_big_endian=False, progress=None, series=None, grid_axes=False,
                 slice_positions=None):
        self._handle = None
        lib = _io_lib()
        self._lib = lib
        self._progress = _Progress(None, io=True)
        self._progress.fn = progress
        opts = _io_options(lib, channel=channel, spacing=spacing, origin=origin, first=first,
                           count=count, step=step, threads=threads, memory_limit=memory_limit,
                           raw_dims=raw_dims, raw_type=raw_type, raw_header=raw_header,
                           raw_big_endian=raw_big_endian, slice_positions=slice_positions)
        opts.progress = self._progress.c_fn
        handle = ctypes.c_void_p()
        status = lib.isomend_io_create(ctypes.byref(handle))
        if status != 0 or not handle.value:
            self._raise(status or 9, "isomend_io_create")
        self._handle = handle
        _dicom_choices(lib, handle, series, grid_axes)
        encoded = _paths_list(paths)
        self.paths = [os.fsdecode(p) for p in encoded]
        arr = (ctypes.c_char_p * len(encoded))(*encoded)
        status = lib.isomend_io_open(handle, arr, len(encoded), ctypes.byref(opts))
        self._check(status, "open")
        self._query()

    @classmethod
    def _adopt(cls, lib, handle, paths):
        """A Source over a handle that a job has opened (or failed to open)."""
        self = cls.__new__(cls)
        self._lib = lib
        self._handle = handle
        self._progress = _Progress(None, io=True)
        self.paths = paths
        return self

    # -- internals
    def _raise(self, status, what):
        msg = ""
        if self._handle is not None:
            raw = self._lib.isomend_io_message(self._handle)
            msg = raw.decode(errors="replace") if raw else ""
        if not msg:
            raw = self._lib.isomend_io_status_string(status)
            msg = raw.decode() if raw else "status %d" % status
        name = IO_STATUS_NAMES.get(status, str(status))
        cls = Cancelled if status == IO_ERR_CANCELLED else IsomendError
        exc = cls(msg if what is None else "%s: %s" % (what, msg), status, name)
        exc.series = self._series_list() if self._handle is not None else []
        raise exc

    def _series_list(self):
        lib, h = self._lib, self._handle
        out = []
        for i in range(int(lib.isomend_io_series_count(h))):
            e = IOSeries()
            e.size = ctypes.sizeof(IOSeries)
            if lib.isomend_io_series_get(h, i, ctypes.byref(e)) == 0:
                out.append({"index": i + 1, "uid": (e.uid or b"").decode(errors="replace"),
                            "description": (e.description or b"").decode(errors="replace"),
                            "modality": (e.modality or b"").decode(errors="replace"),
                            "number": e.number, "files": e.files, "images": e.images,
                            "columns": e.columns, "rows": e.rows})
        return out

    def _check(self, status, what):
        self._progress.reraise()
        if status != 0:
            if self._progress.cancelled and status == IO_ERR_CANCELLED:
                self._progress.cancelled = False
            self._raise(status, what)

    def _require_open(self):
        if self._handle is None:
            raise ValueError("source is closed")
        return self._handle

    def _query(self):
        lib, h = self._lib, self._handle
        dims = (ctypes.c_int64 * 3)()
        self._check(lib.isomend_io_dims(h, dims), "dims")
        self.dims = tuple(dims)
        t = ctypes.c_int()
        self._check(lib.isomend_io_type(h, ctypes.byref(t)), "type")
        self.dtype = _TYPE_TO_DTYPE[t.value]
        sp = (ctypes.c_double * 3)()
        src = (ctypes.c_int * 3)()
        self._check(lib.isomend_io_spacing(h, sp, src), "spacing")
        self.spacing = tuple(sp)
        self.spacing_sources = tuple((lib.isomend_io_spacing_source_name(s) or b"?").decode() for s in src)
        org = (ctypes.c_double * 3)()
        self._check(lib.isomend_io_origin(h, org), "origin")
        self.origin = tuple(org)
        kind = lib.isomend_io_source_kind(h)
        name = lib.isomend_io_kind_name(kind)
        self.kind = name.decode() if name else str(kind)
        fmt = lib.isomend_io_format(h)
        self.format = fmt.decode() if fmt else ""
        self.volume_bytes = int(lib.isomend_io_volume_bytes(h))
        self.slice_bytes = int(lib.isomend_io_slice_bytes(h))
        self.series = self._series_list()
        A = (ctypes.c_double * 12)()
        identity = ctypes.c_int(1)
        self._check(lib.isomend_io_world_transform(h, A, ctypes.byref(identity)), "world transform")
        self.world_transform = None if identity.value else np.array(A[:], float).reshape(3, 4)
        self.dicom = None
        info = IODicom()
        info.size = ctypes.sizeof(IODicom)
        if lib.isomend_io_dicom_info(h, ctypes.byref(info)) == 0:
            text = lambda b: (b or b"").decode(errors="replace")
            self.dicom = {
                "modality": text(info.modality), "series_uid": text(info.series_uid),
                "description": text(info.description), "transfer_syntax": text(info.transfer_syntax),
                "transfer_syntax_name": text(info.transfer_syntax_name),
                "photometric": text(info.photometric), "bits_stored": info.bits_stored,
                "signed": bool(info.pixel_signed), "rescaled": bool(info.rescaled),
                "hounsfield": bool(info.hounsfield), "rescale_slope": info.rescale_slope,
                "rescale_intercept": info.rescale_intercept, "orientation": tuple(info.orientation),
                "normal": tuple(info.normal), "position": tuple(info.position), "files": info.files,
                "multiframe": bool(info.multiframe), "non_image": info.non_image,
                "non_dicom": info.non_dicom, "other_series": info.other_series,
                "axes": "grid" if info.axes == IO_AXES_GRID else "patient",
                "series_index": int(lib.isomend_io_series_chosen(h)) + 1}
        lvl = lib.isomend_io_suggested_level(h)
        self.suggested_level = IO_LEVEL_NAMES[lvl] if 0 <= lvl < len(IO_LEVEL_NAMES) else "otsu"
        geo = IOGeometry()
        geo.size = ctypes.sizeof(IOGeometry)
        self._check(lib.isomend_io_geometry_info(h, ctypes.byref(geo)), "geometry")
        self.geometry = {
            "uniform": bool(geo.uniform), "gap_median": geo.gap_median, "gap_min": geo.gap_min,
            "gap_max": geo.gap_max, "tilt_degrees": geo.tilt_degrees, "max_offset": geo.max_offset,
            "long_gaps": int(geo.long_gaps), "uneven_gaps": int(geo.uneven_gaps),
            "warning": (geo.warning or b"").decode(errors="replace")}
        origins = lib.isomend_io_slice_origins(h)
        self.slice_origins = (np.ctypeslib.as_array(origins, shape=(self.dims[2], 3)).copy()
                              if origins else None)

    def level(self, name):
        """The value of a named iso level: "otsu" (analyses the volume), or for
        a CT series in HU "bone" (300) and "skin" (-500)."""
        if name not in IO_LEVEL_NAMES:
            raise ValueError("level: expected one of %s, got %r" % (", ".join(IO_LEVEL_NAMES), name))
        v = ctypes.c_double()
        self._check(self._lib.isomend_io_level_value(self._require_open(), IO_LEVEL_NAMES.index(name),
                                                     ctypes.byref(v)), "level %s" % name)
        return v.value

    def _with_progress(self, progress):
        if progress is not None:
            self._progress.fn = progress

    # -- public
    def slice_path(self, k):
        """Path of slice k (the file itself for every page of a multi-page file)."""
        p = self._lib.isomend_io_slice_path(self._require_open(), int(k))
        if p is None:
            raise IndexError("slice %d out of range 0..%d" % (k, self.dims[2] - 1))
        return os.fsdecode(p)

    def read(self, progress=None):
        """Reads the whole volume into a new numpy array [z, y, x] of ``dtype``."""
        h = self._require_open()
        self._with_progress(progress)
        nx, ny, nz = self.dims
        out = np.empty((nz, ny, nx), self.dtype)
        self._check(self._lib.isomend_io_read(h, out.ctypes.data, out.nbytes), "read")
        return out

    def read_slice(self, k):
        """Reads slice k into a new numpy array [y, x] (opens and closes the file)."""
        h = self._require_open()
        nx, ny, nz = self.dims
        if not 0 <= int(k) < nz:
            raise IndexError("slice %d out of range 0..%d" % (k, nz - 1))
        out = np.empty((ny, nx), self.dtype)
        self._check(self._lib.isomend_io_read_slice(h, int(k), out.ctypes.data, out.nbytes),
                    "read slice %d" % k)
        return out

    def analyse(self, progress=None):
        """Value range, 16-bin histogram, NaN count and the suggested iso (Otsu)."""
        h = self._require_open()
        self._with_progress(progress)
        s = IOSummary()
        self._check(self._lib.isomend_io_analyse(h, ctypes.byref(s)), "analyse")
        return {"min": s.min, "max": s.max, "samples": s.samples, "nan_samples": s.nan_samples,
                "histogram": list(s.histogram), "suggested_iso": s.suggested_iso,
                "read_seconds": s.read_seconds}

    def extract(self, iso=None, method="dmc", pad=False, flip=False, normals=True, origins=True,
                threads=0, progress=None, small_pages=False):
        """Loads the volume and extracts its isosurface (isomend_io_extract).
        iso None: the importer's suggested level (see analyse()).  Spacing and
        origin are the source's.  Returns a Mesh whose ``iso`` is the level used."""
        h = self._require_open()
        self._with_progress(progress)
        # Load first (isomend_io_extract reuses the buffer): a read error is named
        # "load", and the volume as delivered is known (see _describe).
        described = self._describe()
        # Progress of the extraction goes through the source's callback (stage "extract").
        opts = _options(iso if iso is not None else 0.0, method, pad, flip, normals, origins,
                        threads, None, small_pages)
        handle = ctypes.c_void_p()
        stats = Stats()
        iso_used = ctypes.c_double()
        status = self._lib.isomend_io_extract(h, ctypes.byref(opts), 1 if iso is None else 0,
                                              ctypes.byref(iso_used), ctypes.byref(handle),
                                              ctypes.byref(stats))
        return self._mesh(status, "extract", handle, stats, iso_used.value, opts.method, normals,
                          origins, described)

    def _describe(self):
        """Loads the volume (at once if it is loaded) and returns (Volume, read
        seconds): the origin and spacing of the volume as delivered.  A file whose
        axis points the negative way (NRRD "space directions" (-2,0,0)) is read with
        a negative stride, so its sample (0, 0, 0) is not the file's first sample."""
        vol = Volume()
        seconds = ctypes.c_double()
        self._check(self._lib.isomend_io_load(self._handle, ctypes.byref(vol), ctypes.byref(seconds)),
                    "load")
        return vol, seconds.value

    def _mesh(self, status, what, handle, stats, iso_used, method_id, normals, origins,
              described=None):
        """The Mesh of an isomend_io_extract() (or job) that returned ``status``;
        ``described`` is _describe()'s answer if the caller has it."""
        if status != 0 and handle.value:
            _core_lib().isomend_mesh_destroy(handle)
        self._check(status, what)
        world = getattr(self, "world_transform", None)
        mesh = _take_mesh(handle, stats, iso_used, method_id, normals, origins, world)
        self._place(mesh, world, described)
        return mesh

    def _place(self, mesh, world, described=None):
        """Sets a mesh's volume_origin, volume_spacing and read_seconds."""
        vol, seconds = described or self._describe()
        origin = np.array(vol.origin[:], float)
        if vol.slice_origins:  # slices where they are: sample (0, 0, 0) is on the first
            origin = np.array(ctypes.cast(vol.slice_origins, ctypes.POINTER(ctypes.c_double))[:3], float)
        if world is not None:  # sample (0, 0, 0) in patient space
            origin = world[:, :3] @ origin + world[:, 3]
        mesh.volume_origin = tuple(origin.tolist())
        mesh.volume_spacing = tuple(vol.spacing)
        mesh.read_seconds = seconds

    def label_names(self, label_table=None):
        """The names and colours of this source's labels: from ``label_table``
        (a colour table file: 3D Slicer, FreeSurfer LUT, ITK-SNAP), else from a
        3D Slicer .seg.nrrd's Segment*_ keys (isomend_io_label_names_read).
        Returns a _LabelNames (empty for other sources)."""
        h = self._require_open()
        names = ctypes.c_void_p()
        path = os.fsencode(label_table) if label_table is not None else None
        self._check(self._lib.isomend_io_label_names_read(h, path, ctypes.byref(names)),
                    "label_table" if path else "label names")
        return _LabelNames(self._lib, names)

    def extract_labels(self, labels=None, method="dmc", pad=True, flip=False, normals=True,
                       origins=True, threads=0, progress=None, label_table=None):
        """Loads the volume and extracts the surface of each label of this label
        map (isomend_io_labels_extract): see extract_labels() for the
        arguments and the result.  Float samples are taken when all are whole
        numbers (NIfTI uint32 arrives so); names and colours from
        ``label_table``, else a .seg.nrrd's own keys, else label_N and a palette.
        The meshes are placed as Source.extract()'s (a NIfTI or DICOM file's
        world transform included)."""
        h = self._require_open()
        self._with_progress(progress)
        values, count = _labels_argument(labels)
        opts = _label_options(method, pad, flip, normals, origins, threads, None)
        names = self.label_names(label_table)  # a bad table is refused before any work
        with names:
            described = self._describe()
            result = ctypes.c_void_p()
            status = self._lib.isomend_io_labels_extract(h, values, count, ctypes.byref(opts),
                                                         ctypes.byref(result))
            if status != 0 and result.value:
                _core_lib().isomend_labels_destroy(result)
            self._check(status, "labels")
            world = getattr(self, "world_transform", None)
            meshes = _label_meshes(result, opts.method, normals, origins, world, names)
        for mesh in meshes.values():
            self._place(mesh, world, described)
        return meshes

    def close(self):
        """Releases the handle and the loaded volume (idempotent)."""
        if self._handle is not None:
            h, self._handle = self._handle, None
            self._lib.isomend_io_destroy(h)

    def __repr__(self):
        return "<isomend.Source %s %s %dx%dx%d %s spacing=%s>" % (
            self.kind, self.format, self.dims[0], self.dims[1], self.dims[2],
            np.dtype(self.dtype).name, self.spacing)


def _type_id(t):
    if isinstance(t, str):
        out = ctypes.c_int()
        if _core_lib().isomend_type_from_name(t.encode(), ctypes.byref(out)) == 0:
            return out.value
    try:
        dt = np.dtype(t)
    except TypeError:
        dt = None
    if dt is not None and dt in _DTYPE_TO_TYPE:
        return _DTYPE_TO_TYPE[dt]
    raise ValueError("raw_type: expected u8, i8, u16, i16, i32, f32, f64 (or a numpy dtype), got %r" % (t,))


class ExtractJob(_Closable):
    """extract_source() on a thread of the C library's own (isomend_io_job_*).

    No Python code runs on that thread, so a host that does not support Python
    threads (Blender) can keep its interface running meanwhile: poll() the job
    from the host's timer, cancel() it on Esc, and take its result() once
    poll() says it is done::

        job = isomend.ExtractJob("scan/", iso=None)
        while not job.poll()[2]:
            time.sleep(0.1)            # a UI timer in a real host
        mesh, info = job.result()

    The arguments are extract_source()'s, without ``progress`` (poll instead);
    they are checked here, before the thread starts.  result() raises what
    extract_source() would (Cancelled after cancel()).  close() (or garbage
    collection) cancels a job that is still running and waits for its thread.
    """

    def __init__(self, paths, iso=None, method="dmc", pad=False, flip=False, normals=True,
                 origins=True, threads=0, small_pages=False, **open_kwargs):
        if "progress" in open_kwargs:
            raise TypeError("progress: a job calls no callback; poll() it instead")
        self._job = None
        self._handle = None
        lib = self._lib = _io_lib()
        series = open_kwargs.pop("series", None)
        grid_axes = open_kwargs.pop("grid_axes", False)
        io_opts = self._io_opts = _io_options(lib, threads=threads, **open_kwargs)
        self._opts = _options(iso if iso is not None else 0.0, method, pad, flip, normals, origins,
                              threads, None, small_pages)
        self._want = (normals, origins)
        encoded = _paths_list(paths)
        self.paths = [os.fsdecode(p) for p in encoded]
        handle = ctypes.c_void_p()
        status = lib.isomend_io_create(ctypes.byref(handle))
        if status != 0 or not handle.value:
            raise IsomendError("isomend_io_create: out of memory", status or 9,
                               IO_STATUS_NAMES.get(status or 9, "?"))
        self._handle = handle
        _dicom_choices(lib, handle, series, grid_axes)
        arr = (ctypes.c_char_p * len(encoded))(*encoded)
        job = ctypes.c_void_p()
        status = lib.isomend_io_job_start(handle, arr, len(encoded), ctypes.byref(io_opts),
                                          ctypes.byref(self._opts), 1 if iso is None else 0,
                                          ctypes.byref(job))
        if status != 0:
            self._handle = None
            with Source._adopt(lib, handle, self.paths) as src:  # which frees the handle
                src._raise(status, "start")
        self._job = job

    def poll(self):
        """(stage, fraction, done): the stage ("open", "read", "analyse",
        "extract") and the fraction of it last reported; done is True once the
        work has ended (result() then returns at once).  Never blocks."""
        if self._job is None:
            return ("extract", 1.0, True)
        stage, fraction = ctypes.c_int(), ctypes.c_double()
        done = self._lib.isomend_io_job_poll(self._job, ctypes.byref(stage), ctypes.byref(fraction))
        name = IO_STAGES[stage.value] if 0 <= stage.value < len(IO_STAGES) else str(stage.value)
        return (name, fraction.value, bool(done))

    def cancel(self):
        """Asks the job to stop at its next progress point; never blocks."""
        if self._job is not None:
            self._lib.isomend_io_job_cancel(self._job)

    def result(self):
        """Waits for the job and returns (mesh, info): the Mesh, and a dict of the
        source's dims, dtype, spacing, spacing_sources, origin, kind, format, dicom,
        world_transform, geometry and slice_origins (see Source).
        Raises IsomendError (Cancelled if cancelled).  Once only."""
        if self._job is None:
            raise ValueError("the job's result was already taken")
        job, self._job = self._job, None
        handle, stats, iso_used = ctypes.c_void_p(), Stats(), ctypes.c_double()
        status = self._lib.isomend_io_job_finish(job, ctypes.byref(iso_used), ctypes.byref(handle),
                                                 ctypes.byref(stats))
        src = Source._adopt(self._lib, self._handle, self.paths)
        self._handle = None
        with src:
            # the failing call named as Source and Source.extract name it
            if self._lib.isomend_io_source_kind(src._handle) < 0:  # the open failed
                src._check(status, "open")
            src._query()
            mesh = src._mesh(status, "extract", handle, stats, iso_used.value, self._opts.method,
                             *self._want)
            info = {"dims": src.dims, "dtype": np.dtype(src.dtype).name, "spacing": src.spacing,
                    "spacing_sources": src.spacing_sources, "origin": src.origin,
                    "kind": src.kind, "format": src.format, "dicom": src.dicom,
                    "world_transform": src.world_transform, "geometry": src.geometry,
                    "slice_origins": src.slice_origins}
        return mesh, info

    def close(self):
        """Cancels the job if it still runs, waits for its thread, frees it all."""
        job, self._job = self._job, None
        if job is not None:
            self._lib.isomend_io_job_cancel(job)
            self._lib.isomend_io_job_finish(job, None, None, None)
        handle, self._handle = self._handle, None
        if handle is not None:
            self._lib.isomend_io_destroy(handle)


def open_source(paths, **kwargs):
    """Opens and validates a source: a folder, a glob ('scan/*.tif'), a printf
    pattern ('s_%04d.tif' with first/count/step), a list of files, a multi-page
    TIFF, a raw file (raw_dims, raw_type), an NRRD file or a DICOM series (a
    folder, a DICOMDIR, DICOM files, a multi-frame file).  Keyword arguments:
    channel (index, 'auto', 'luma'), spacing, origin, first, count, step, threads,
    memory_limit, raw_dims, raw_type, raw_header, raw_big_endian, slice_positions
    (the z of each slice when they are not evenly spaced), progress;
    for DICOM series (a 1-based position or a UID) and grid_axes.
    Returns a Source; raises IsomendError naming the file and the reason."""
    return Source(paths, **kwargs)


def extract_labels_source(paths, labels=None, method="dmc", pad=True, flip=False, normals=True,
                          origins=True, threads=0, progress=None, label_table=None, **open_kwargs):
    """open_source(paths, **open_kwargs) then Source.extract_labels(...): a
    label map file (NIfTI, NRRD or 3D Slicer .seg.nrrd, raw with raw_dims and
    raw_type, an image stack) to {value: Mesh}."""
    with Source(paths, threads=threads, progress=progress, **open_kwargs) as src:
        return src.extract_labels(labels=labels, method=method, pad=pad, flip=flip,
                                  normals=normals, origins=origins, threads=threads,
                                  label_table=label_table)


def extract_source(paths, iso=None, method="dmc", pad=False, flip=False, normals=True,
                   origins=True, threads=0, progress=None, small_pages=False, **open_kwargs):
    """open_source(paths, **open_kwargs) then Source.extract(...): one call from
    files to a Mesh; iso None uses the suggested level."""
    with Source(paths, threads=threads, progress=progress, **open_kwargs) as src:
        return src.extract(iso=iso, method=method, pad=pad, flip=flip, normals=normals,
                           origins=origins, threads=threads, small_pages=small_pages)
