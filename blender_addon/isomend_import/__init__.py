"""Blender add-on: File > Import > Slice Stack as Isosurface (isomend).

A thin host adapter (CONTRIBUTING.md): the algorithm is in libisomend, the file reading in
libisomend_io, both reached through the bpy-free ctypes module ``isomend.py``;
everything else that needs no Blender (which files, which iso, the job, the
mesh arrays, the report) is in ``import_stack.py``, as Blender's own importers
keep their logic out of ``__init__.py``.  This file holds the operator, its
properties, progress, reports and the Blender mesh.

One source for Blender 3.4 to 4.3: ``bl_info`` for the legacy add-on zip,
``blender_manifest.toml`` (next to this file) for the extension package of
Blender 4.2+, where the module is ``bl_ext.<repository>.isomend_import``;
imports are relative, and the mesh code checks the API it uses
(``use_auto_smooth`` before 4.1, ``loop_total`` writable before 4.0).

Conventions:
  - iso: an ``iso`` that is set (passed by a script, typed in the panel) is
    the level used; otherwise, with ``use_suggested_iso`` (default), the
    importer's suggested level (Otsu).  Typing a level unticks the box,
    ticking the box unsets the level.  The level used is reported and stored
    on the object as the custom property ``isomend_iso``.
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
    A series whose slices are not evenly spaced (positions rounded by the
    scanner, a spacing change, a gantry tilt, a missing slice) is meshed at
    its slices' true positions; the importer's warning is reported at
    WARNING level after the import's INFO report.
  - the object is placed at the volume's origin (sample (0, 0, 0)); its
    vertices are relative to it.
  - normals: ``smooth`` shades the faces smooth; with ``gradient_normals``
    too (default) the core's gradient normals become custom split normals
    (the volume's exact surface normals, ~2 s more per million triangles);
    without ``smooth`` the faces are flat.
  - a multi-file selection is put in natural order (s_2 before s_10).
  - Label Map (a segmentation: NIfTI, 3D Slicer .seg.nrrd, NRRD, raw, a
    stack): ``labels`` "all" (every value but 0) or "1,5,7"; one object per
    label, named after it, with a material of its colour (sRGB from the
    table, linear in Blender), all in one new collection named after the
    file; names and colours from ``label_table`` (a colour table file),
    else a .seg.nrrd's own segments, else label_N and a palette.  Iso and
    the post-processing do not apply.  The label map is imported
    synchronously (the library's job thread extracts isosurfaces only).
  - post-processing (Minimum Component, Smooth Iterations, Decimate Ratio; all
    0 = off) runs on the extracted mesh in the command line's order, on
    Blender's main thread after the library's thread ends (not cancellable);
    the report says what each step did.

Cancellation: in the interactive UI the import runs on a thread of the C
library's own (``isomend.ExtractJob``, isomend_io_job_start) while a modal
operator polls its progress on a timer and updates the progress indicator;
Esc cancels (the library stops at its next progress point).  No Python code
runs off Blender's main thread: Blender does not support Python threads
("Python threads cause Blender to crash in hard to diagnose ways", its API
documentation); an earlier version that ran the import in a Python
``threading.Thread`` saw one unexplained crash when Esc cancelled it (see
docs/blender.md).  Run from a script or in background mode (blender -b) the import runs
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

import time

import bpy
import numpy as np
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       FloatVectorProperty, IntProperty, StringProperty)
from bpy.types import Operator, OperatorFileListElement
from bpy_extras.io_utils import ImportHelper

from . import import_stack
from . import isomend

# Blender needs the enum's item strings kept referenced while the enum is in
# use, hence the module cache.
_method_items_cache = []

# Outcome of the last finished import: {"status": 'FINISHED' or 'CANCELLED',
# "message": the report, "warning": the importer's warning on the slices'
# geometry (also reported at WARNING level), or ""}.  Lets a script that
# started the import modally (it returns {'RUNNING_MODAL'} at once) find out
# how it ended.
last_import = {}


def _method_items(_self, _context):
    if not _method_items_cache:
        _method_items_cache.extend(import_stack.method_items())
    return _method_items_cache


# Update callbacks keep the panel truthful about import_stack.choose_iso (an
# iso that is set wins).  Blender calls them with the operator's properties
# when the panel changes a value, and also for keyword arguments of a
# bpy.ops call, in the order the properties are declared (use_suggested_iso
# before iso), so a script's iso is never unset by them.
def _iso_changed(self, _context):
    # A level typed in the panel (or passed) is the level used: the box follows.
    if self.use_suggested_iso:
        self.use_suggested_iso = False


def _suggested_changed(self, _context):
    # Ticking the box hands the level back to the importer's suggestion.
    if self.use_suggested_iso and self.is_property_set("iso"):
        self.property_unset("iso")


class IMPORT_MESH_OT_slice_stack(Operator, ImportHelper):
    """Import a slice stack (folder of images, selected files or a multi-page TIFF) as an isosurface mesh"""
    bl_idname = "import_mesh.slice_stack"
    bl_label = "Slice Stack as Isosurface"
    bl_options = {'REGISTER', 'UNDO'}

    filename_ext = ""
    filter_glob: StringProperty(
        default="*.tif;*.tiff;*.png;*.exr;*.jpg;*.jpeg;*.bmp;*.dpx;*.jp2;*.hdr;*.nrrd;*.nhdr;*.dcm;DICOMDIR;*.nii;*.nii.gz;*.img",
        options={'HIDDEN'})
    directory: StringProperty(subtype='DIR_PATH', options={'HIDDEN', 'SKIP_SAVE'})
    files: CollectionProperty(type=OperatorFileListElement, options={'HIDDEN', 'SKIP_SAVE'})

    use_suggested_iso: BoolProperty(
        name="Suggested Iso Level",
        description="Use the importer's suggested iso level (Otsu's threshold of the histogram). "
                    "An Iso Level that is set (typed here, or passed by a script) is used instead",
        default=True, update=_suggested_changed)
    iso: FloatProperty(
        name="Iso Level",
        description="Samples >= this value are inside the surface (in the images' own units, "
                    "e.g. 0..65535 for 16-bit)",
        default=0.0, precision=3, update=_iso_changed)
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
    # post-processing of the extracted mesh, in the command line's order
    # (isomend.postprocess): clean-up, smoothing, decimation; 0 = off
    min_component: IntProperty(
        name="Minimum Component",
        description="Drop the connected pieces of the mesh with fewer triangles than this "
                    "(specks of noise); 0 = keep everything",
        default=0, min=0, max=2**31 - 1)
    smooth_iterations: IntProperty(
        name="Smooth Iterations",
        description="Windowed sinc smoothing iterations that remove the voxel staircase without shrinking "
                    "(the enclosed volume is restored; the surface stays closed); 0 = off",
        default=0, min=0, max=10000, soft_max=100)
    decimate: FloatProperty(
        name="Decimate Ratio",
        description="Fraction of the triangles to keep (0.2 = a fifth), by quadric edge collapse "
                    "that keeps the surface closed and 2-manifold; 0 = off",
        default=0.0, min=0.0, max=1.0, precision=3, subtype='FACTOR')
    # a label map (segmentation): one object per label, in a new collection
    label_map: BoolProperty(
        name="Label Map",
        description="The volume is a label map (a segmentation): one closed object per label, "
                    "named and coloured, in a new collection (Iso Level and post-processing "
                    "are not used)",
        default=False)
    labels: StringProperty(
        name="Labels",
        description="The labels to import: all (every value but 0, the background), or "
                    "values such as 1,5,7",
        default="all")
    label_table: StringProperty(
        name="Colour Table",
        description="Names and colours of the labels: a 3D Slicer colour table, FreeSurfer's "
                    "FreeSurferColorLUT.txt or an ITK-SNAP label description. Empty: a "
                    ".seg.nrrd's own segments, else label_N and a fixed palette",
        default="", subtype='FILE_PATH')
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
        layout.label(text="Label Map")
        layout.prop(self, "label_map")
        col = layout.column()
        col.active = self.label_map
        col.prop(self, "labels")
        col.prop(self, "label_table")
        layout.label(text="Post-processing")
        layout.prop(self, "min_component")
        layout.prop(self, "smooth_iterations")
        layout.prop(self, "decimate")

    # ---------------------------------------------------------------- inputs
    def _iso(self):
        return import_stack.choose_iso(self.use_suggested_iso, self.iso,
                                       self.properties.is_property_set("iso"))

    def _job(self):
        """The import the properties ask for, or raises ValueError with the reason."""
        directory = bpy.path.abspath(self.directory) if self.directory else ""
        filepath = bpy.path.abspath(self.filepath) if self.filepath else ""
        paths = import_stack.resolve_paths(directory, [f.name for f in self.files], filepath)
        spacing = import_stack.spacing_argument(self.spacing)
        return import_stack.ImportJob(paths, self._iso(), self.method.lower(), spacing,
                                      self.channel, self.pad, self.smooth and self.gradient_normals,
                                      series=self.series.strip() or None, grid_axes=self.grid_axes,
                                      decimate=self.decimate,
                                      smooth_iterations=self.smooth_iterations,
                                      min_component=self.min_component,
                                      labels=self.labels.strip() if self.label_map else None,
                                      label_table=(bpy.path.abspath(self.label_table)
                                                   if self.label_map and self.label_table.strip()
                                                   else None))

    # ---------------------------------------------------------------- running
    def invoke(self, context, event):
        self.modal_ui = True
        # An iso remembered from a script's call wins (choose_iso): show it so.
        if self.properties.is_property_set("iso") and self.use_suggested_iso:
            self.properties.property_unset("iso")
        return ImportHelper.invoke(self, context, event)

    def execute(self, context):
        try:
            job = self._job()
        except ValueError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        if (self.modal_ui and not bpy.app.background and context.window is not None
                and job.labels is None):
            # Cleared so that a redo (Adjust Last Operation) runs synchronously.
            self.modal_ui = False
            return self._start_modal(context, job)
        wm = context.window_manager
        wm.progress_begin(0, 1000)
        try:
            if bpy.app.background:
                job.printer = import_stack.BackgroundPrinter(lambda line: print(line, flush=True))
            else:
                job.printer = lambda stage, fraction: wm.progress_update(
                    int(1000 * import_stack.overall(stage, fraction)))
            job.run()
            if not bpy.app.background:
                wm.progress_update(int(1000 * import_stack.overall("mesh", 0.0)))
            return self._finish(context, job)
        finally:
            wm.progress_end()

    def _start_modal(self, context, job):
        try:
            job.start()
        except Exception as exc:  # refused before anything ran
            self.report({'ERROR'}, str(exc))
            last_import.clear()
            last_import.update(status='CANCELLED', message=str(exc), warning="")
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
            last_import.update(status='CANCELLED', message="Import cancelled: Blender ended the operator",
                               warning="")

    def modal(self, context, event):
        job = self._job_obj
        wm = context.window_manager
        if event.type == 'ESC':
            job.request_cancel()  # the library stops at its next progress point
        if event.type == 'TIMER':
            done = job.poll()
            wm.progress_update(int(1000 * import_stack.overall(job.stage, job.fraction)))
            if context.workspace is not None:
                context.workspace.status_text_set(
                    "isomend: %s %d%%%s" % (job.stage, int(100 * job.fraction),
                                            " (cancelling)" if job.cancel else " - Esc to cancel"))
            if done:
                self._job_obj = None
                wm.event_timer_remove(self._timer)
                wm.progress_update(int(1000 * import_stack.overall("mesh", 0.0)))
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
        status, message, warning = self._finish_inner(context, job)
        # The outcome of the last import, for scripts that started it modally;
        # "warning": the importer's warning on the slices' geometry, or "".
        last_import.clear()
        last_import.update(status=status, message=message, warning=warning)
        return {status}

    def _finish_inner(self, context, job):
        status, level, message = job.outcome()
        if status != 'FINISHED':
            self.report({level}, message)
            return status, message, ""
        if job.labels is not None:
            return self._finish_labels(context, job)
        mesh, info = job.result
        name = import_stack.stack_name(job.paths)
        t0 = time.perf_counter()
        try:
            obj = _make_object(context, name, import_stack.mesh_buffers(mesh, self.unit_scale),
                               self.smooth)
        except Exception as exc:  # e.g. out of memory in Blender: nothing is left behind
            self.report({'ERROR'}, "could not build the mesh: %s" % exc)
            return 'CANCELLED', "could not build the mesh: %s" % exc, ""
        for key, value in import_stack.custom_properties(mesh, info).items():
            obj[key] = value
        msg = import_stack.report(obj.name, mesh, info, suggested=job.iso is None)
        self.report({'INFO'}, msg)
        # slices not evenly spaced (a DICOM series with a spacing change, a
        # gantry tilt, a missing slice): meshed where they are, and said so
        warning = import_stack.geometry_warning(obj.name, info)
        if warning:
            self.report({'WARNING'}, warning)
        if bpy.app.background:
            print("isomend: %s (read + extract %.2f s, Blender mesh %.2f s)"
                  % (msg, job.seconds, time.perf_counter() - t0), flush=True)
        return 'FINISHED', msg, warning


    def _finish_labels(self, context, job):
        """One object per label, with a material of its colour, in a new
        collection; nothing is left behind if any of it fails."""
        meshes, info = job.result
        name = import_stack.label_collection_name(job.paths)
        t0 = time.perf_counter()
        collection = bpy.data.collections.new(name)
        made = []
        try:
            (context.collection or context.scene.collection).children.link(collection)
            for value, mesh in meshes.items():
                obj = _make_object(context, mesh.name, import_stack.mesh_buffers(mesh, self.unit_scale),
                                   self.smooth, collection=collection, select_only=not made)
                made.append(obj)
                mat = bpy.data.materials.new(mesh.name)
                mat.diffuse_color = import_stack.srgb_to_linear(mesh.color)
                obj.data.materials.append(mat)
                obj["isomend_label"] = int(value)
                obj["isomend_voxels"] = int(mesh.voxels)
                obj["isomend_method"] = mesh.method
                obj["isomend_spacing_mm"] = [float(s) for s in info["spacing"]]
        except Exception as exc:  # e.g. out of memory in Blender: nothing is left behind
            for obj in made:
                me, mats = obj.data, list(obj.data.materials)
                bpy.data.objects.remove(obj)
                bpy.data.meshes.remove(me)
                for mat in mats:
                    if mat is not None:
                        bpy.data.materials.remove(mat)
            bpy.data.collections.remove(collection)
            self.report({'ERROR'}, "could not build the label objects: %s" % exc)
            return 'CANCELLED', "could not build the label objects: %s" % exc, ""
        msg = import_stack.label_report(name, meshes, info)
        self.report({'INFO'}, msg)
        if bpy.app.background:
            print("isomend: %s (read + extract %.2f s, Blender objects %.2f s)"
                  % (msg, job.seconds, time.perf_counter() - t0), flush=True)
        return 'FINISHED', msg, ""


def _make_object(context, name, buffers, smooth, collection=None, select_only=True):
    """Builds the Blender mesh and object from import_stack.MeshBuffers, in
    ``collection`` (default: the active one), selected and active (with
    ``select_only`` the only selected object); removes both if anything fails."""
    nt = buffers.triangle_count
    me = bpy.data.meshes.new(name)
    obj = None
    try:
        me.vertices.add(buffers.vertex_count)
        me.vertices.foreach_set("co", buffers.coords)
        me.loops.add(3 * nt)
        me.loops.foreach_set("vertex_index", buffers.loop_vertices)
        me.polygons.add(nt)
        me.polygons.foreach_set("loop_start", buffers.loop_starts)
        if not bpy.types.MeshPolygon.bl_rna.properties["loop_total"].is_readonly:
            # Blender < 4.0 stores sizes; 4.0+ derives them from loop_start.
            me.polygons.foreach_set("loop_total", buffers.loop_totals)
        me.update(calc_edges=True)
        if nt:  # explicit both ways: faces are smooth by default in Blender 4.1+, flat before
            me.polygons.foreach_set("use_smooth", np.full(nt, bool(smooth)))
        if smooth and buffers.normals is not None and nt:
            if hasattr(me, "use_auto_smooth"):  # Blender < 4.1 needs it for custom normals
                me.use_auto_smooth = True
                me.auto_smooth_angle = np.pi  # never split: the gradient normals are per vertex
            # A list is parsed ~3x faster than a numpy array (element by element) here.
            me.normals_split_custom_set_from_vertices(buffers.normals.tolist())
        obj = bpy.data.objects.new(me.name, me)
        obj.location = buffers.location
        collection = collection or context.collection or context.scene.collection
        collection.objects.link(obj)
        if select_only:
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
