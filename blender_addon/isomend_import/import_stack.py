"""The bpy-free half of the add-on "Slice Stack as Isosurface".

Blender's own importers keep their operators in ``__init__.py`` and the work
in a module of its own (``io_mesh_ply/import_ply.py``); this is that module.
It holds everything the operator does that is not a call into Blender:

  - which files make the stack (``resolve_paths``, natural order),
  - which iso level is used (``choose_iso``: an iso the caller set wins),
  - what the object is called (``stack_name``),
  - the import itself (``ImportJob``: run in the calling thread with progress,
    or started on the C library's own thread and polled),
  - the arrays Blender's mesh is built from (``mesh_buffers``), the custom
    properties, the report and the importer's warning on the slices'
    geometry (``geometry_warning``: a DICOM series whose slices are not
    evenly spaced is meshed where they are, and the user is told),
  - the check that the bundled libraries can load on this system
    (``library_problem``) before anything is attempted.

Plain Python with numpy can import and test it (tests/blender/test_import_stack.py).
"""

import json
import os
import re
import time

import numpy as np

from . import isomend

# ------------------------------------------------------------ the files

_NATURAL = re.compile(r"(\d+)")


def natural_key(name):
    """Sort key: runs of digits compare as numbers (s_2 before s_10)."""
    return [int(part) if part.isdigit() else part.lower() for part in _NATURAL.split(name)]


def resolve_paths(directory, names, filepath=""):
    """The source paths of an import: ``directory`` alone (the folder), or the
    ``names`` selected in it in natural order; ``filepath`` (a file or folder)
    when no directory is given.  Paths must be absolute already (the operator
    resolves Blender's "//" first).  Raises ValueError with the reason."""
    names = [n for n in names if n]
    if not directory and filepath:
        if os.path.isdir(filepath):
            directory = filepath
        else:
            directory, name = os.path.split(filepath)
            names = names or [name]
    if not directory:
        raise ValueError("no folder or file chosen")
    if not os.path.isdir(directory):
        raise ValueError("folder not found: %s" % directory)
    if not names:
        return [directory]
    return [os.path.join(directory, n) for n in sorted(names, key=natural_key)]


def spacing_argument(spacing):
    """The operator's spacing (x, y, z) as the wrapper takes it: None for
    (0, 0, 0), "from the files"; ValueError unless all three are > 0."""
    spacing = tuple(float(s) for s in spacing)
    if all(s == 0.0 for s in spacing):
        return None
    if any(not s > 0.0 for s in spacing):
        raise ValueError("spacing: all three values must be > 0, or all 0 to read them from "
                         "the files (got %g, %g, %g)" % spacing)
    return spacing


def choose_iso(use_suggested_iso, iso, iso_is_set):
    """The iso level to ask the importer for, None meaning its suggestion.

    An iso the caller set (``bpy.ops.import_mesh.slice_stack(iso=237.5)``, or
    typed in the panel) is never ignored, whatever ``use_suggested_iso`` says:
    the suggestion is used only when no iso was set and the box is ticked.
    (Ticking the box in the interface unsets the iso, so the box and the
    level shown always agree there.)"""
    if iso_is_set or not use_suggested_iso:
        return float(iso)
    return None


# Folder names that say nothing about the stack: the parent's name is used.
GENERIC_FOLDERS = {"tif", "tiff", "png", "exr", "jpg", "dcm", "dicom", "slices", "images",
                   "image", "stack", "data"}


def stack_name(paths):
    """Object name: the folder's name (its parent's for a generic name such as
    "tiff" or "slices"), a single file's stem, or the common prefix of a file
    list (without trailing digits/separators)."""
    first = paths[0].rstrip("/\\")
    if len(paths) == 1:
        if os.path.isdir(first):
            name = os.path.basename(first)
            if name.lower() in GENERIC_FOLDERS:
                name = os.path.basename(os.path.dirname(first)) or name
            return name or "slice_stack"
        return os.path.splitext(os.path.basename(first))[0] or "slice_stack"
    prefix = os.path.commonprefix([os.path.basename(p) for p in paths])
    prefix = prefix.rstrip("0123456789_-. ")
    return prefix or os.path.basename(os.path.dirname(first)) or "slice_stack"


# ------------------------------------------------------------ methods

# The three methods of the thesis come first; methods added to the library
# later (isomend_method_available) follow in id order.
FIXED_METHODS = (
    ("DMC", "DMC (mended)", "Marching cubes plus a quadrilateral on every inverted combination: "
     "no holes, no extra polygons (the thesis method)"),
    ("MC", "Marching cubes", "Lorensen & Cline 1987: may leave holes at ambiguous faces"),
    ("DURST", "Durst", "Marching cubes plus a quadrilateral on every ambiguous face: no holes, "
     "but extraneous polygons"),
)


def method_items():
    """The items of the operator's method enum: (identifier, name, description, number)."""
    items = [(ident, name, desc, i) for i, (ident, name, desc) in enumerate(FIXED_METHODS)]
    try:
        if library_problem() is None:
            fixed = {ident.lower() for ident, _, _ in FIXED_METHODS}
            for name, available in isomend.methods():
                if available and name not in fixed:
                    items.append((name.upper(), name.capitalize(), "isomend method '%s'" % name,
                                  isomend.METHODS.get(name, len(items))))
    except isomend.IsomendError:
        pass  # library missing: the fixed items; the import reports the reason
    return items


# ------------------------------------------------------------ progress

# Share of each stage in the overall progress bar.
STAGE_SPAN = {"open": (0.0, 0.05), "read": (0.05, 0.55), "analyse": (0.55, 0.6),
              "extract": (0.6, 0.9), "postprocess": (0.9, 0.92), "mesh": (0.92, 1.0)}


def overall(stage, fraction):
    """The overall progress (0..1) of ``fraction`` of ``stage``."""
    lo, hi = STAGE_SPAN.get(stage, (0.0, 1.0))
    return lo + (hi - lo) * min(max(fraction, 0.0), 1.0)


class BackgroundPrinter:
    """Prints progress in background mode (Blender's progress indicator is a
    no-op there): one line per stage and every 25 %."""

    def __init__(self, out=print):
        self.last = (None, -1)
        self.out = out

    def __call__(self, stage, fraction):
        step = int(fraction * 4)
        if (stage, step) != self.last and (stage != self.last[0] or step > self.last[1]):
            self.last = (stage, step)
            self.out("isomend: %-7s %3d%%" % (stage, int(fraction * 100)))


# ------------------------------------------------------------ the import

class ImportJob:
    """One import: open, extract.  Either run() it in the calling thread, with
    progress callbacks; or start() it on the C library's own thread and poll()
    it from the main thread (no callback, no Python thread: Blender does not
    support Python threads).  Afterwards ``result`` is (mesh, info) or
    ``error`` the exception; ``cancel`` says whether a cancel was asked."""

    def __init__(self, paths, iso, method, spacing, channel, pad, normals, series=None,
                 grid_axes=False, decimate=0.0, smooth_iterations=0, min_component=0,
                 labels=None, label_table=None):
        self.paths = paths
        # a label map (issue 36): labels "all" or "1,5,7" (None: an isosurface);
        # names and colours from label_table, else a .seg.nrrd's own keys
        self.labels = labels
        self.label_table = label_table or None
        if labels is not None and (decimate or smooth_iterations or min_component):
            raise ValueError("Label Map: the post-processing (Minimum Component, Smooth "
                             "Iterations, Decimate Ratio) does not apply to a label map")
        if labels is None and self.label_table:
            raise ValueError("Colour Table: only for a Label Map")
        # post-processing of the extracted mesh, in the command line's order
        # (isomend.postprocess): clean-up, smoothing, decimation; 0 = off
        self.min_component = min_component
        self.smooth_iterations = smooth_iterations
        self.decimate = decimate
        isomend.check_postprocess(**self._post_arguments())  # ValueError before anything runs
        self.series = series        # DICOM: which series (None: the only one)
        self.grid_axes = grid_axes  # DICOM: the series' own axes, not patient space
        self.iso = iso          # None: the importer's suggestion
        self.method = method
        self.spacing = spacing  # None: from the files
        self.channel = channel
        self.pad = pad
        self.normals = normals
        self.stage = "open"
        self.fraction = 0.0
        self.cancel = False
        self.printer = None  # callable(stage, fraction), e.g. BackgroundPrinter()
        self.result = None   # (mesh, source info dict)
        self.error = None
        self.seconds = 0.0
        self._native = None  # isomend.ExtractJob after start()
        self._t0 = 0.0

    def progress(self, stage, fraction):
        self.stage, self.fraction = stage, fraction
        if self.printer is not None:
            self.printer(stage, fraction)
        return self.cancel

    def run(self):
        """Imports in the calling thread; never raises (see ``error``)."""
        t0 = time.perf_counter()
        try:
            problem = library_problem()
            if problem is not None:
                raise isomend.LibraryNotFound(problem)
            with isomend.open_source(self.paths, channel=self.channel, spacing=self.spacing,
                                     progress=self.progress, series=self.series,
                                     grid_axes=self.grid_axes) as src:
                info = {"dims": src.dims, "dtype": np.dtype(src.dtype).name,
                        "spacing": src.spacing, "spacing_sources": src.spacing_sources,
                        "origin": src.origin, "kind": src.kind, "format": src.format,
                        "dicom": src.dicom, "geometry": src.geometry,
                        "slice_origins": src.slice_origins}
                if self.labels is not None:  # {value: Mesh}
                    self.result = (src.extract_labels(labels=self.labels, method=self.method,
                                                      pad=self.pad, normals=self.normals,
                                                      progress=self.progress,
                                                      label_table=self.label_table), info)
                    info["names_from"] = next(iter(self.result[0].values())).names_from
                    return
                mesh = src.extract(iso=self.iso, method=self.method, pad=self.pad,
                                   normals=self.normals, origins=True, progress=self.progress)
            self.result = (self._postprocess(mesh), info)
        except Exception as exc:  # reported by the caller
            self.error = exc
        finally:
            self.seconds = time.perf_counter() - t0

    def start(self):
        """Starts the import on the C library's thread; raises if the
        arguments are refused (nothing runs then).  A label map has no job of
        the library's own: run() it."""
        if self.labels is not None:
            raise ValueError("a label map is imported with run(), not on the library's thread")
        problem = library_problem()
        if problem is not None:
            raise isomend.LibraryNotFound(problem)
        self._t0 = time.perf_counter()
        self._native = isomend.ExtractJob(self.paths, iso=self.iso, method=self.method,
                                          pad=self.pad, normals=self.normals, origins=True,
                                          channel=self.channel, spacing=self.spacing,
                                          series=self.series, grid_axes=self.grid_axes)

    def request_cancel(self):
        self.cancel = True
        if self._native is not None:
            self._native.cancel()

    def poll(self):
        """Records the progress; True once the import has ended, with
        ``result`` or ``error`` set.  Never blocks."""
        if self._native is None:
            return True
        self.stage, self.fraction, done = self._native.poll()
        if done:
            native, self._native = self._native, None
            try:
                mesh, info = native.result()  # at once: the thread has ended
                if not self.cancel:  # Esc as the extraction ended: nothing more is done
                    self.result = (self._postprocess(mesh), info)
            except Exception as exc:
                self.error = exc
            finally:
                native.close()
            self.seconds = time.perf_counter() - self._t0
        return done

    def abandon(self):
        """Cancels a started import and waits for the library's thread."""
        if self._native is not None:
            native, self._native = self._native, None
            native.close()

    def _post_arguments(self):
        return {"decimate": self.decimate or None, "smooth": int(self.smooth_iterations),
                "min_component": int(self.min_component)}

    def _postprocess(self, mesh):
        """The post-processing steps asked for (on the calling thread: the
        core's calls, no progress points); the mesh itself when none."""
        args = self._post_arguments()
        if not (args["decimate"] or args["smooth"] or args["min_component"]):
            return mesh
        self.progress("postprocess", 0.0)
        mesh = isomend.postprocess(mesh, **args)
        self.progress("postprocess", 1.0)
        return mesh

    def outcome(self):
        """('FINISHED', None) when there is a mesh to build, else ('CANCELLED',
        report level, message): cancelled by the user (also when Esc came as
        the work ended: nothing is built after the fact) or failed."""
        if self.cancel and self.error is None:
            return 'CANCELLED', 'WARNING', "Import cancelled"
        if isinstance(self.error, isomend.Cancelled):
            return 'CANCELLED', 'WARNING', "Import cancelled"
        if self.error is not None:
            return 'CANCELLED', 'ERROR', str(self.error)
        return 'FINISHED', None, None


# ------------------------------------------------------------ the mesh

class MeshBuffers:
    """What a Blender mesh is built from, as the arrays ``foreach_set`` takes
    fastest (float32 and int32): vertex coordinates relative to the object's
    location (flat, x y z ...), each triangle's three corners (loops) as vertex
    indices, each polygon's first loop, and the object's location (the
    volume's origin, sample (0, 0, 0)); all scaled by ``unit_scale`` (Blender
    units per millimetre).  ``normals`` are the core's unit gradient normals
    per vertex, (V, 3) float32, or None."""

    def __init__(self, mesh, unit_scale):
        origin = np.asarray(mesh.volume_origin, dtype=np.float64)
        positions = mesh.positions
        if np.any(origin != 0.0):
            positions = (positions.astype(np.float64) - origin).astype(np.float32)
        self.vertex_count = int(mesh.vertex_count)
        self.triangle_count = int(mesh.triangle_count)
        self.coords = (positions.reshape(-1) * np.float32(unit_scale)).astype(np.float32, copy=False)
        self.loop_vertices = mesh.triangles.reshape(-1).view(np.int32)
        self.loop_starts = np.arange(0, 3 * self.triangle_count, 3, dtype=np.int32)
        self.loop_totals = np.full(self.triangle_count, 3, dtype=np.int32)
        self.location = tuple(float(o) * unit_scale for o in origin)
        self.normals = mesh.normals


def mesh_buffers(mesh, unit_scale):
    return MeshBuffers(mesh, unit_scale)


def custom_properties(mesh, info):
    """The object's custom properties: what was imported, and how."""
    props = {"isomend_iso": float(mesh.iso), "isomend_method": mesh.method,
             "isomend_mending_triangles": int(mesh.stats["mending_triangles"]),
             "isomend_spacing_mm": [float(s) for s in info["spacing"]]}
    dicom = info.get("dicom")
    if dicom:
        props["isomend_dicom_series_uid"] = dicom["series_uid"]
        props["isomend_dicom_axes"] = dicom["axes"]
    return props


def geometry_text(info):
    """How the slices lie, for the report: "" when they are evenly spaced (or
    unknown), else where their gaps differ ("slices not evenly spaced (gaps
    1.2 to 2.5 mm), meshed at their positions")."""
    geo = info.get("geometry")
    if not geo or geo["uniform"]:
        return ""
    text = "slices not evenly spaced (gaps %g to %g mm" % (geo["gap_min"], geo["gap_max"])
    if geo["tilt_degrees"] > 0:
        text += ", tilt %.3g degrees" % geo["tilt_degrees"]
    return text + "), meshed at their positions"


def geometry_warning(name, info):
    """The importer's warning on the slices' geometry (uneven gaps, a long gap
    where slices may be missing), with the object's name; "" if none."""
    geo = info.get("geometry")
    return "%s: %s" % (name, geo["warning"]) if geo and geo["warning"] else ""


def report(name, mesh, info, suggested):
    """The one-line report of a finished import."""
    sp = info["spacing"]
    msg = ("Imported %s: %d vertices, %d triangles (%d mending), iso %g%s, %s, %dx%dx%d samples, "
           "spacing %g x %g x %g mm (%s)"
           % (name, mesh.vertex_count, mesh.triangle_count, mesh.stats["mending_triangles"],
              mesh.iso, " (suggested)" if suggested else "", mesh.method.upper(),
              info["dims"][0], info["dims"][1], info["dims"][2], sp[0], sp[1], sp[2],
              ", ".join(info["spacing_sources"])))
    dicom = info.get("dicom")
    if dicom:
        msg += ("; DICOM %s series \"%s\", %s axes%s"
                % (dicom["modality"], dicom["description"], dicom["axes"],
                   " (bone level, HU)" if dicom["hounsfield"] and suggested else ""))
    geometry = geometry_text(info)
    if geometry:
        msg += "; " + geometry
    post = postprocess_text(mesh)
    if post:
        msg += "; " + post
    return msg


def label_collection_name(paths):
    """A label map's collection: stack_name() without a segmentation's inner
    extension ("organs.seg.nrrd" -> "organs", "seg.nii.gz" -> "seg")."""
    name = stack_name(paths)
    for inner in (".seg", ".nii"):
        if name.lower().endswith(inner) and len(name) > len(inner):
            return name[:-len(inner)]
    return name


def srgb_to_linear(rgb):
    """A label's colour (r, g, b) 0..255, sRGB as colour tables give it, as
    Blender's linear RGBA (a material's diffuse_color), alpha 1."""
    out = []
    for c in rgb:
        c = c / 255.0
        out.append(c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4)
    return tuple(out) + (1.0,)


def label_report(name, meshes, info):
    """The one-line report of a label map's import."""
    sp = info["spacing"]
    first = next(iter(meshes.values()))
    parts = ", ".join("%d %s: %d triangles" % (value, m.name, m.triangle_count)
                      for value, m in meshes.items())
    return ("Imported %s: %d label%s (%s), %s, %dx%dx%d samples, spacing %g x %g x %g mm, "
            "names from %s"
            % (name, len(meshes), "" if len(meshes) == 1 else "s", parts, first.method.upper(),
               info["dims"][0], info["dims"][1], info["dims"][2], sp[0], sp[1], sp[2],
               first.names_from or "none (label_N)"))


def postprocess_text(mesh):
    """What the post-processing did, for the report ("" when nothing ran):
    components kept, the smoothing's volume change, the decimation's counts,
    whether its target was reached, and its largest error."""
    post = getattr(mesh, "postprocess", None) or {}
    parts = []
    c = post.get("clean")
    if c:
        parts.append("clean-up: %d of %d components kept (%d triangles removed)"
                     % (c["components_after"], c["components_before"], c["triangles_removed"]))
    s = post.get("smooth")
    if s:
        v0, v1 = s["volume_before"], s["volume_after"]
        parts.append("smoothed: %d vertices moved, volume %+.3f %%"
                     % (s["moved_vertices"], 100.0 * (v1 - v0) / v0 if v0 else 0.0))
    d = post.get("decimate")
    if d:
        parts.append("decimated: %d -> %d triangles (target %d %s), largest error %.3g mm"
                     % (d["triangles_before"], d["triangles_after"], d["target_triangles"],
                        "reached" if d["reached"] else "not reached", d["max_error"]))
    return "; ".join(parts)


# ------------------------------------------------------------ can the libraries load?

# Written next to the bundled libraries by the build (blender_addon/tools/bundle.py):
# {"glibc": "2.36", "libraries": [...], "built_on": "..."}.
BUILD_INFO = os.path.join(os.path.dirname(os.path.abspath(__file__)), "lib", "build-info.json")
_problem_cache = []


def _version_tuple(text):
    return tuple(int(p) for p in re.findall(r"\d+", text)[:3])


def system_glibc():
    """The running C library's version ("2.36"), or None if it is not glibc."""
    try:
        name = os.confstr("CS_GNU_LIBC_VERSION") or ""
    except (AttributeError, ValueError, OSError):
        return None
    parts = name.split()
    return parts[1] if len(parts) == 2 and parts[0] == "glibc" else None


def library_problem(build_info=None, glibc=None):
    """None if the package's libraries can be loaded here, else a sentence
    saying why not: they need a newer glibc than this system's (the package
    records the highest GLIBC_ symbol version its libraries reference), or
    loading them failed.  Checked once per session (the arguments are for
    tests)."""
    if build_info is None and glibc is None and _problem_cache:
        return _problem_cache[0]
    path = build_info or BUILD_INFO
    problem = None
    need = None
    if os.path.exists(path):
        try:
            with open(path) as fp:
                need = json.load(fp).get("glibc")
        except (OSError, ValueError) as exc:
            problem = "the add-on's %s is unreadable (%s): reinstall the add-on" % (path, exc)
    have = glibc if glibc is not None else system_glibc()
    if problem is None and need and have and _version_tuple(have) < _version_tuple(need):
        problem = ("the add-on's libraries need glibc %s or newer and this system has glibc %s: "
                   "use a build of the add-on made on a system as old as this one (see "
                   "docs/blender.md, 'Which systems')" % (need, have))
    if problem is None and build_info is None and glibc is None:
        try:
            isomend.version()
            isomend.io_version()
        except isomend.IsomendError as exc:
            problem = "the add-on's libraries cannot be loaded on this system: %s" % exc
    if build_info is None and glibc is None:
        _problem_cache.append(problem)
    return problem
