"""Blender add-on: File > Import > Slice Stack as Isosurface (isomend).

A thin host adapter (CONTRIBUTING.md): the algorithm is in libisomend, the
file reading in libisomend_io, both reached through the bpy-free ctypes module
``isomend.py`` next to this file (plain Python can import and test it).  This
file only turns operator properties into wrapper arguments, forwards progress
to Blender's progress indicator, reports errors and builds the mesh with
``foreach_set`` on float32/int32 arrays.

Conventions:
  - iso: with ``use_suggested_iso`` (default) the importer's suggested level
    (Otsu) is used and ``iso`` is ignored; the level used is reported and
    stored on the object as the custom property ``isomend_iso``.
  - spacing (x, y, z) in millimetres; (0, 0, 0), the default, means "from the
    files' metadata (TIFF resolution, ImageJ spacing, NRRD header), else 1".
  - unit_scale: Blender units per millimetre, default 0.001 (1 unit = 1 metre,
    Blender's default scene units, so a 250 mm head is 0.25 m tall).
  - axes: x = image column, y = image row (top row first), z = slice order,
    as isomend_io.h documents: the mesh is the stack as an image viewer shows
    it, moved and scaled, never mirrored.  A DICOM series is placed in patient
    coordinates (LPS mm: Blender's +X the patient's left, +Y posterior, +Z the
    head, so the Front view shows the face), turned by its direction cosines;
    ``grid_axes`` keeps the series' own axes; ``series`` picks one of several.
  - the object is placed at the volume's origin (sample (0, 0, 0)); its
    vertices are relative to it.
  - normals: ``smooth`` shades the faces smooth; with ``gradient_normals``
    too (default) the core's gradient normals become custom split normals
    (the volume's exact surface normals, ~2 s more per million triangles);
    without ``smooth`` the faces are flat.
  - a multi-file selection is put in natural order (s_2 before s_10).

Cancellation: in the interactive UI the import runs on a thread of the C
library's own (``isomend.ExtractJob``, isomend_io_job_start) while a modal
operator polls its progress on a timer and updates the progress indicator;
Esc cancels (the library stops at its next progress point).  No Python code
runs off Blender's main thread: Blender does not support Python threads
("Python threads cause Blender to crash in hard to diagnose ways", its API
documentation); an earlier version that ran the import in a Python
``threading.Thread`` saw one unexplained crash when Esc cancelled it (see the
README).  Run from a script or in background mode (blender -b) the import runs
synchronously and prints progress instead.
"""

bl_info = {
    "name": "Slice Stack as Isosurface (isomend)",
    "author": "isomend contributors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "File > Import > Slice Stack as Isosurface",
    "description": "Import a stack of 2D images (CT, MRI, microscopy) as a hole-free isosurface mesh",
    "category": "Import-Export",
}

import os
import re
import time

import bpy
import numpy as np
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       FloatVectorProperty, IntProperty, StringProperty)
from bpy.types import Operator, OperatorFileListElement
from bpy_extras.io_utils import ImportHelper

from . import isomend

# The three methods of the thesis come first; methods added to the library
# later (isomend_method_available) follow in id order.  Blender needs the item
# strings kept referenced while the enum is in use, hence the module cache.
_FIXED_METHODS = (
    ("DMC", "DMC (mended)", "Marching cubes plus a quadrilateral on every inverted combination: "
     "no holes, no extra polygons (the thesis method)"),
    ("MC", "Marching cubes", "Lorensen & Cline 1987: may leave holes at ambiguous faces"),
    ("DURST", "Durst", "Marching cubes plus a quadrilateral on every ambiguous face: no holes, "
     "but extraneous polygons"),
)
_method_items_cache = []

# Outcome of the last finished import: {"status": 'FINISHED' or 'CANCELLED',
# "message": the report}.  Lets a script that started the import modally (it
# returns {'RUNNING_MODAL'} at once) find out how it ended.
last_import = {}


def _method_items(_self, _context):
    if not _method_items_cache:
        items = [(ident, name, desc, i) for i, (ident, name, desc) in enumerate(_FIXED_METHODS)]
        try:
            fixed = {ident.lower() for ident, _, _ in _FIXED_METHODS}
            for name, available in isomend.methods():
                if available and name not in fixed:
                    items.append((name.upper(), name.capitalize(), "isomend method '%s'" % name,
                                  isomend.METHODS.get(name, len(items))))
        except isomend.IsomendError:
            pass  # library missing: the fixed items; execute() reports the reason
        _method_items_cache.extend(items)
    return _method_items_cache


_NATURAL = re.compile(r"(\d+)")


def _natural_key(name):
    return [int(part) if part.isdigit() else part.lower() for part in _NATURAL.split(name)]


# Folder names that say nothing about the stack: the parent's name is used.
_GENERIC_FOLDERS = {"tif", "tiff", "png", "exr", "jpg", "slices", "images", "image", "stack", "data"}


def _stack_name(paths):
    """Object name: the folder's name (its parent's for a generic name such as
    "tiff" or "slices"), a single file's stem, or the common prefix of a file
    list (without trailing digits/separators)."""
    first = paths[0].rstrip("/\\")
    if len(paths) == 1:
        if os.path.isdir(first):
            name = os.path.basename(first)
            if name.lower() in _GENERIC_FOLDERS:
                name = os.path.basename(os.path.dirname(first)) or name
            return name or "slice_stack"
        return os.path.splitext(os.path.basename(first))[0] or "slice_stack"
    prefix = os.path.commonprefix([os.path.basename(p) for p in paths])
    prefix = prefix.rstrip("0123456789_-. ")
    return prefix or os.path.basename(os.path.dirname(first)) or "slice_stack"


# Share of each stage in the overall progress bar.
_STAGE_SPAN = {"open": (0.0, 0.05), "read": (0.05, 0.55), "analyse": (0.55, 0.6),
               "extract": (0.6, 0.92), "mesh": (0.92, 1.0)}


def _overall(stage, fraction):
    lo, hi = _STAGE_SPAN.get(stage, (0.0, 1.0))
    return lo + (hi - lo) * min(max(fraction, 0.0), 1.0)


class _Job:
    """The bpy-free part of one import: open, extract.  Either run() in the
    calling thread, with progress callbacks; or start() it on the C library's
    own thread and poll() it from the main thread (no callback, no Python
    thread)."""

    def __init__(self, paths, iso, method, spacing, channel, pad, normals, series=None,
                 grid_axes=False):
        self.paths = paths
        self.series = series
        self.grid_axes = grid_axes
        self.iso = iso
        self.method = method
        self.spacing = spacing
        self.channel = channel
        self.pad = pad
        self.normals = normals
        self.stage = "open"
        self.fraction = 0.0
        self.cancel = False
        self.printer = None  # callable(stage, fraction) for background mode
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
        t0 = time.perf_counter()
        try:
            with isomend.open_source(self.paths, channel=self.channel, spacing=self.spacing,
                                     progress=self.progress, series=self.series,
                                     grid_axes=self.grid_axes) as src:
                info = {"dims": src.dims, "dtype": np.dtype(src.dtype).name,
                        "spacing": src.spacing, "spacing_sources": src.spacing_sources,
                        "origin": src.origin, "kind": src.kind, "dicom": src.dicom}
                mesh = src.extract(iso=self.iso, method=self.method, pad=self.pad,
                                   normals=self.normals, origins=True, progress=self.progress)
            self.result = (mesh, info)
        except Exception as exc:  # reported by the caller
            self.error = exc
        self.seconds = time.perf_counter() - t0

    def start(self):
        """Starts the import on the C library's thread; raises if the
        arguments are refused (nothing runs then)."""
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
                self.result = native.result()  # at once: the thread has ended
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


class IMPORT_MESH_OT_slice_stack(Operator, ImportHelper):
    """Import a slice stack (folder of images, selected files or a multi-page TIFF) as an isosurface mesh"""
    bl_idname = "import_mesh.slice_stack"
    bl_label = "Slice Stack as Isosurface"
    bl_options = {'REGISTER', 'UNDO'}

    filename_ext = ""
    filter_glob: StringProperty(
        default="*.tif;*.tiff;*.png;*.exr;*.jpg;*.jpeg;*.bmp;*.dpx;*.jp2;*.hdr;*.nrrd;*.nhdr;*.dcm;DICOMDIR",
        options={'HIDDEN'})
    directory: StringProperty(subtype='DIR_PATH', options={'HIDDEN', 'SKIP_SAVE'})
    files: CollectionProperty(type=OperatorFileListElement, options={'HIDDEN', 'SKIP_SAVE'})

    use_suggested_iso: BoolProperty(
        name="Suggested Iso Level",
        description="Use the importer's suggested iso level (Otsu's threshold of the histogram) "
                    "instead of Iso Level",
        default=True)
    iso: FloatProperty(
        name="Iso Level",
        description="Samples >= this value are inside the surface (in the images' own units, "
                    "e.g. 0..65535 for 16-bit)",
        default=0.0, precision=3)
    method: EnumProperty(name="Method", description="Isosurface method", items=_method_items)
    spacing: FloatVectorProperty(
        name="Spacing (mm)",
        description="Distance between samples along x (columns), y (rows), z (slices) in "
                    "millimetres; 0, 0, 0 = from the files' metadata, else 1",
        size=3, default=(0.0, 0.0, 0.0), min=0.0, precision=4, subtype='XYZ')
    unit_scale: FloatProperty(
        name="Unit Scale",
        description="Blender units per millimetre (0.001: 1 unit = 1 metre)",
        default=0.001, min=1e-9, max=1e6, precision=4)
    channel: IntProperty(
        name="Channel",
        description="Image channel to use: -1 = the only channel (an error if there are several), "
                    "-2 = luminance of R, G, B, 0.. = that channel",
        default=-1, min=-2, max=64)
    pad: BoolProperty(
        name="Close at Border",
        description="Surround the volume with one layer of outside samples, so the surface is "
                    "closed where it touches the volume's border",
        default=True)
    smooth: BoolProperty(
        name="Smooth Shading",
        description="Shade the faces smooth (off: flat shading)",
        default=True)
    gradient_normals: BoolProperty(
        name="Gradient Normals",
        description="With smooth shading, use the volume's gradient normals as custom split normals "
                    "(exact surface normals of the volume; costs about 2 s per million triangles). "
                    "Off: Blender's own vertex normals",
        default=True)
    series: StringProperty(
        name="DICOM Series",
        description="For a folder holding several DICOM series: the series' number as the error "
                    "message lists them (1, 2, ...) or its Series Instance UID. Empty: the only series",
        default="")
    grid_axes: BoolProperty(
        name="DICOM Grid Axes",
        description="Keep a DICOM series' own axes (columns, rows, slices) instead of placing the "
                    "mesh in patient coordinates (LPS mm, turned by the series' orientation)",
        default=False)
    modal_ui: BoolProperty(options={'HIDDEN', 'SKIP_SAVE'}, default=False)

    def draw(self, _context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "use_suggested_iso")
        row = layout.row()
        row.active = not self.use_suggested_iso
        row.prop(self, "iso")
        layout.prop(self, "method")
        layout.prop(self, "spacing")
        layout.prop(self, "unit_scale")
        layout.prop(self, "channel")
        layout.prop(self, "pad")
        layout.prop(self, "series")
        layout.prop(self, "grid_axes")
        layout.prop(self, "smooth")
        row = layout.row()
        row.active = self.smooth
        row.prop(self, "gradient_normals")

    # ---------------------------------------------------------------- inputs
    def _paths(self):
        """The source paths, or raises ValueError with the reason."""
        directory = bpy.path.abspath(self.directory) if self.directory else ""
        names = [f.name for f in self.files if f.name]
        if not directory and self.filepath:
            path = bpy.path.abspath(self.filepath)
            if os.path.isdir(path):
                directory = path
            else:
                directory, name = os.path.split(path)
                names = names or [name]
        if not directory:
            raise ValueError("no folder or file chosen")
        if not os.path.isdir(directory):
            raise ValueError("folder not found: %s" % directory)
        if not names:
            return [directory]
        names.sort(key=_natural_key)
        return [os.path.join(directory, n) for n in names]

    def _job(self):
        paths = self._paths()
        spacing = tuple(self.spacing)
        if all(s == 0.0 for s in spacing):
            spacing = None
        elif any(s <= 0.0 for s in spacing):
            raise ValueError("spacing: all three values must be > 0, or all 0 to read them from "
                             "the files (got %g, %g, %g)" % spacing)
        return _Job(paths, None if self.use_suggested_iso else self.iso, self.method.lower(),
                    spacing, self.channel, self.pad, self.smooth and self.gradient_normals,
                    series=self.series.strip() or None, grid_axes=self.grid_axes)

    # ---------------------------------------------------------------- running
    def invoke(self, context, event):
        self.modal_ui = True
        return ImportHelper.invoke(self, context, event)

    def execute(self, context):
        try:
            job = self._job()
        except ValueError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        if self.modal_ui and not bpy.app.background and context.window is not None:
            # Cleared so that a redo (Adjust Last Operation) runs synchronously.
            self.modal_ui = False
            return self._start_modal(context, job)
        wm = context.window_manager
        wm.progress_begin(0, 1000)
        try:
            if bpy.app.background:
                job.printer = _BackgroundPrinter()
            else:
                job.printer = lambda stage, fraction: wm.progress_update(int(1000 * _overall(stage, fraction)))
            job.run()
            if not bpy.app.background:
                wm.progress_update(int(1000 * _overall("mesh", 0.0)))
            return self._finish(context, job)
        finally:
            wm.progress_end()

    def _start_modal(self, context, job):
        try:
            job.start()
        except Exception as exc:  # refused before anything ran
            self.report({'ERROR'}, str(exc))
            last_import.clear()
            last_import.update(status='CANCELLED', message=str(exc))
            return {'CANCELLED'}
        self._job_obj = job
        wm = context.window_manager
        wm.progress_begin(0, 1000)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def cancel(self, context):
        # Blender ends a running modal operator this way (loading a file,
        # closing the window): stop the library's thread before the operator goes.
        job = getattr(self, "_job_obj", None)
        if job is not None:
            self._job_obj = None
            job.abandon()
            context.window_manager.event_timer_remove(self._timer)
            context.window_manager.progress_end()
            last_import.clear()
            last_import.update(status='CANCELLED', message="Import cancelled: Blender ended the operator")

    def modal(self, context, event):
        job = self._job_obj
        wm = context.window_manager
        if event.type == 'ESC':
            job.request_cancel()  # the library stops at its next progress point
        if event.type == 'TIMER':
            done = job.poll()
            wm.progress_update(int(1000 * _overall(job.stage, job.fraction)))
            if context.workspace is not None:
                context.workspace.status_text_set(
                    "isomend: %s %d%%%s" % (job.stage, int(100 * job.fraction),
                                            " (cancelling)" if job.cancel else " - Esc to cancel"))
            if done:
                self._job_obj = None
                wm.event_timer_remove(self._timer)
                wm.progress_update(int(1000 * _overall("mesh", 0.0)))
                try:
                    return self._finish(context, job)  # builds the mesh: progress stays up
                finally:
                    wm.progress_end()
                    if context.workspace is not None:
                        context.workspace.status_text_set(None)
            return {'RUNNING_MODAL'}
        if event.type == 'ESC':
            return {'RUNNING_MODAL'}
        return {'PASS_THROUGH'}  # the viewport stays usable meanwhile

    # ---------------------------------------------------------------- result
    def _finish(self, context, job):
        status, message = self._finish_inner(context, job)
        # The outcome of the last import, for scripts that started it modally.
        last_import.clear()
        last_import.update(status=status, message=message)
        return {status}

    def _finish_inner(self, context, job):
        # Esc pressed while the worker was finishing: nothing is created yet, so
        # the import is cancelled as the user asked (not built after the fact).
        if job.cancel and job.error is None:
            self.report({'WARNING'}, "Import cancelled")
            return 'CANCELLED', "Import cancelled"
        if job.error is not None:
            exc = job.error
            if isinstance(exc, isomend.Cancelled):
                self.report({'WARNING'}, "Import cancelled")
                return 'CANCELLED', "Import cancelled"
            self.report({'ERROR'}, str(exc))
            return 'CANCELLED', str(exc)
        mesh, info = job.result
        name = _stack_name(job.paths)
        t0 = time.perf_counter()
        try:
            obj = _make_object(context, name, mesh, self.unit_scale, self.smooth)
        except Exception as exc:  # e.g. out of memory in Blender: nothing is left behind
            self.report({'ERROR'}, "could not build the mesh: %s" % exc)
            return 'CANCELLED', "could not build the mesh: %s" % exc
        obj["isomend_iso"] = float(mesh.iso)
        obj["isomend_method"] = mesh.method
        obj["isomend_mending_triangles"] = int(mesh.stats["mending_triangles"])
        obj["isomend_spacing_mm"] = list(info["spacing"])
        dicom = info.get("dicom")
        if dicom:
            obj["isomend_dicom_series_uid"] = dicom["series_uid"]
            obj["isomend_dicom_axes"] = dicom["axes"]
        sp = info["spacing"]
        msg = ("Imported %s: %d vertices, %d triangles (%d mending), iso %g%s, %s, %dx%dx%d samples, "
               "spacing %g x %g x %g mm (%s)"
               % (obj.name, mesh.vertex_count, mesh.triangle_count, mesh.stats["mending_triangles"],
                  mesh.iso, " (suggested)" if job.iso is None else "", mesh.method.upper(),
                  info["dims"][0], info["dims"][1], info["dims"][2], sp[0], sp[1], sp[2],
                  ", ".join(info["spacing_sources"])))
        if dicom:
            msg += ("; DICOM %s series \"%s\", %s axes%s"
                    % (dicom["modality"], dicom["description"], dicom["axes"],
                       " (bone level, HU)" if dicom["hounsfield"] and job.iso is None else ""))
        self.report({'INFO'}, msg)
        if bpy.app.background:
            print("isomend: %s (read + extract %.2f s, Blender mesh %.2f s)"
                  % (msg, job.seconds, time.perf_counter() - t0), flush=True)
        return 'FINISHED', msg


class _BackgroundPrinter:
    """Prints progress in background mode (the progress indicator is a no-op
    there): one line per stage and every 25 %."""

    def __init__(self):
        self.last = (None, -1)

    def __call__(self, stage, fraction):
        step = int(fraction * 4)
        if (stage, step) != self.last and (stage != self.last[0] or step > self.last[1]):
            self.last = (stage, step)
            print("isomend: %-7s %3d%%" % (stage, int(fraction * 100)), flush=True)


def _make_object(context, name, mesh, unit_scale, smooth):
    """Builds the Blender mesh and object; removes both if anything fails."""
    origin = np.asarray(mesh.volume_origin, dtype=np.float64)
    positions = mesh.positions
    if np.any(origin != 0.0):
        positions = (positions.astype(np.float64) - origin).astype(np.float32)
    coords = positions.reshape(-1) * np.float32(unit_scale)
    nv, nt = mesh.vertex_count, mesh.triangle_count
    me = bpy.data.meshes.new(name)
    obj = None
    try:
        me.vertices.add(nv)
        me.vertices.foreach_set("co", coords.astype(np.float32, copy=False))
        me.loops.add(3 * nt)
        me.loops.foreach_set("vertex_index", mesh.triangles.reshape(-1).view(np.int32))
        me.polygons.add(nt)
        me.polygons.foreach_set("loop_start", np.arange(0, 3 * nt, 3, dtype=np.int32))
        if not bpy.types.MeshPolygon.bl_rna.properties["loop_total"].is_readonly:
            # Blender < 4.0 stores sizes; 4.0+ derives them from loop_start.
            me.polygons.foreach_set("loop_total", np.full(nt, 3, dtype=np.int32))
        me.update(calc_edges=True)
        if smooth and nt:
            me.polygons.foreach_set("use_smooth", np.ones(nt, dtype=bool))
        if smooth and mesh.normals is not None and nt:
            if hasattr(me, "use_auto_smooth"):  # Blender < 4.1 needs it for custom normals
                me.use_auto_smooth = True
                me.auto_smooth_angle = np.pi  # never split: the gradient normals are per vertex
            # A list is parsed ~3x faster than a numpy array (element by element) here.
            me.normals_split_custom_set_from_vertices(mesh.normals.tolist())
        obj = bpy.data.objects.new(me.name, me)
        obj.location = tuple(float(o) * unit_scale for o in origin)
        collection = context.collection or context.scene.collection
        collection.objects.link(obj)
        for other in context.selected_objects:
            other.select_set(False)
        obj.select_set(True)
        context.view_layer.objects.active = obj
        return obj
    except BaseException:
        if obj is not None:
            bpy.data.objects.remove(obj)
        bpy.data.meshes.remove(me)
        raise


def menu_func_import(self, _context):
    self.layout.operator(IMPORT_MESH_OT_slice_stack.bl_idname, text="Slice Stack as Isosurface")


classes = (IMPORT_MESH_OT_slice_stack,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.TOPBAR_MT_file_import.append(menu_func_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_func_import)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
