"""pytest tests of blender_addon/isomend_import/import_stack.py, the add-on's
bpy-free half (which files, which iso, the job, the mesh arrays, the report,
the library check), in plain Python with numpy: no Blender.

Run by ctest (blender_logic_pytest) with Debian's python3-pytest:
    ISOMEND_STAGE=<build>/blender_addon/isomend_import python3 -m pytest -q test_import_stack.py
ISOMEND_STAGE is the staged add-on folder (the package with lib/).  The
package's __init__.py needs bpy, so the test makes the package from its
folder without running it (a module whose __path__ is the folder) and
imports import_stack from it: its relative imports work as in Blender.
"""
import json
import os
import sys
import types

import numpy as np
import pytest

STAGE = os.environ.get("ISOMEND_STAGE")
if not STAGE:
    pytest.exit("ISOMEND_STAGE is not set (the staged add-on folder)", returncode=2)
os.environ.pop("ISOMEND_LIB_DIR", None)  # the package's own lib/
_pkg = types.ModuleType("isomend_import")
_pkg.__path__ = [STAGE]
sys.modules["isomend_import"] = _pkg
from isomend_import import import_stack, isomend  # noqa: E402

tifffile = pytest.importorskip("tifffile")


@pytest.fixture(scope="module")
def blob(tmp_path_factory):
    """12 slices s_0.tif .. s_11.tif of a u16 blob in a folder named "tiff"
    inside "knee_scan" (a generic folder name: the object is named after the
    parent)."""
    root = tmp_path_factory.mktemp("blob")
    folder = root / "knee_scan" / "tiff"
    folder.mkdir(parents=True)
    z, y, x = np.meshgrid(np.arange(12.0), np.arange(14.0), np.arange(16.0), indexing="ij")
    vol = (1000 * np.exp(-((x - 7.5) ** 2 + (y - 6.2) ** 2 + (z - 5.3) ** 2) / 12)).astype(np.uint16)
    for k in range(12):
        tifffile.imwrite(str(folder / ("s_%d.tif" % k)), vol[k])
    return {"folder": str(folder), "volume": vol, "names": ["s_%d.tif" % k for k in range(12)]}


# ------------------------------------------------------------ the files

def test_natural_order_puts_2_before_10_and_ignores_case():
    names = ["s_10.tif", "S_2.tif", "s_1.tif", "s_100.tif", "s_02b.tif"]
    assert sorted(names, key=import_stack.natural_key) == [
        "s_1.tif", "S_2.tif", "s_02b.tif", "s_10.tif", "s_100.tif"]


def test_resolve_paths_folder_selection_and_filepath(blob, tmp_path):
    folder = blob["folder"]
    assert import_stack.resolve_paths(folder, []) == [folder]
    assert import_stack.resolve_paths(folder, [""]) == [folder]  # "folder chosen, nothing selected"
    picked = import_stack.resolve_paths(folder, ["s_10.tif", "s_2.tif", "s_1.tif"])
    assert [os.path.basename(p) for p in picked] == ["s_1.tif", "s_2.tif", "s_10.tif"]
    one = os.path.join(folder, "s_3.tif")
    assert import_stack.resolve_paths("", [], one) == [one]
    assert import_stack.resolve_paths("", [], folder) == [folder]
    with pytest.raises(ValueError, match="no folder or file chosen"):
        import_stack.resolve_paths("", [])
    missing = str(tmp_path / "gone")
    with pytest.raises(ValueError, match="folder not found: .*gone"):
        import_stack.resolve_paths(missing, [])


def test_spacing_zero_means_from_the_files_and_partial_spacing_is_refused():
    assert import_stack.spacing_argument((0, 0, 0)) is None
    assert import_stack.spacing_argument((0.5, 0.5, 2)) == (0.5, 0.5, 2.0)
    for bad in ((1, 0, 1), (1, -1, 1), (float("nan"), 1, 1)):
        with pytest.raises(ValueError, match="spacing: all three values must be > 0"):
            import_stack.spacing_argument(bad)


def test_an_iso_that_is_set_always_wins():
    # (use_suggested_iso, iso, iso set by the caller) -> level asked for (None: suggestion)
    assert import_stack.choose_iso(True, 0.0, False) is None          # the defaults
    assert import_stack.choose_iso(True, 237.5, True) == 237.5        # iso=237.5 passed alone
    assert import_stack.choose_iso(False, 237.5, True) == 237.5
    assert import_stack.choose_iso(False, 0.0, False) == 0.0          # box off: the level shown
    assert import_stack.choose_iso(True, 12.0, False) is None         # not set: the suggestion


def test_object_names(blob, tmp_path):
    knee = os.path.dirname(blob["folder"])
    assert import_stack.stack_name([knee]) == "knee_scan"
    assert import_stack.stack_name([blob["folder"] + "/"]) == "knee_scan"   # "tiff" says nothing
    (tmp_path / "data" / "Slices").mkdir(parents=True)
    assert import_stack.stack_name([str(tmp_path / "data" / "Slices")]) == "data"
    assert import_stack.stack_name(["/data/head.nrrd"]) == "head"
    assert import_stack.stack_name(["/d/ct_001.tif", "/d/ct_002.tif"]) == "ct"
    assert import_stack.stack_name(["/d/001.tif", "/d/002.tif"]) == "d"


def test_method_items_start_with_the_thesis_methods_and_list_the_library_ones():
    items = import_stack.method_items()
    assert [i[0] for i in items[:3]] == ["DMC", "MC", "DURST"]
    numbers = [i[3] for i in items]
    assert len(set(numbers)) == len(numbers)
    names = {i[0].lower() for i in items}
    assert names == {"dmc", "mc", "durst"} | set(isomend.available_methods())


def test_overall_progress_is_monotone_and_clamped():
    order = ["open", "read", "analyse", "extract", "postprocess", "mesh"]
    values = [import_stack.overall(s, f) for s in order for f in (0.0, 0.5, 1.0)]
    assert values == sorted(values) and values[0] == 0.0 and values[-1] == 1.0
    assert import_stack.overall("read", -1) == import_stack.overall("read", 0)
    assert import_stack.overall("read", 7) == import_stack.overall("read", 1)


def test_background_printer_prints_each_stage_and_quarter_once():
    lines = []
    p = import_stack.BackgroundPrinter(lines.append)
    for stage in ("read", "extract"):
        for f in (0.0, 0.1, 0.3, 0.3, 0.6, 0.99, 1.0):
            p(stage, f)
    assert lines == ["isomend: %-7s %3d%%" % (s, v) for s in ("read", "extract")
                     for v in (0, 30, 60, 99, 100)]


# ------------------------------------------------------------ the import

def job(paths, iso=None, method="dmc", spacing=None, pad=True, normals=True):
    return import_stack.ImportJob(paths, iso, method, spacing, -1, pad, normals)


def same(a, b):
    assert (a.vertex_count, a.triangle_count) == (b.vertex_count, b.triangle_count)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.triangles, b.triangles)


def test_run_gives_the_wrappers_mesh_at_the_suggested_or_the_given_iso(blob):
    j = job([blob["folder"]], spacing=(0.5, 0.5, 2.0))
    j.run()
    assert j.error is None and j.outcome() == ('FINISHED', None, None)
    mesh, info = j.result
    want = isomend.extract_source(blob["folder"], spacing=(0.5, 0.5, 2.0), pad=True)
    same(mesh, want)
    assert info["dims"] == (16, 14, 12) and info["dtype"] == "uint16" and info["format"] == "tiff"
    assert info["spacing"] == (0.5, 0.5, 2.0) and info["kind"] == "folder"
    j = job([blob["folder"]], iso=300.0, method="mc")
    j.run()
    assert j.result[0].iso == 300.0 and j.result[0].method == "mc"


def test_start_and_poll_give_the_same_mesh(blob):
    j = job([blob["folder"]], iso=250.0)
    j.start()
    while not j.poll():
        pass
    assert j.outcome()[0] == 'FINISHED' and j.seconds > 0
    same(j.result[0], isomend.extract_source(blob["folder"], iso=250.0, pad=True))


def test_cancel_and_errors_end_cancelled_with_the_reason(blob, tmp_path):
    j = job([blob["folder"]])
    j.printer = lambda stage, fraction: j.request_cancel()   # Esc at the first report
    j.run()
    assert isinstance(j.error, isomend.Cancelled)
    assert j.outcome() == ('CANCELLED', 'WARNING', "Import cancelled")
    # Esc as the work ended without error: still cancelled, nothing is built
    j = job([blob["folder"]])
    j.run()
    j.cancel = True
    assert j.outcome() == ('CANCELLED', 'WARNING', "Import cancelled")
    # started, then abandoned (Blender ended the operator): the thread is joined
    j = job([blob["folder"]])
    j.start()
    j.abandon()
    assert j.poll() is True
    # a mismatched stack: an error naming the file
    bad = tmp_path / "mismatch"
    bad.mkdir()
    for k in range(3):
        tifffile.imwrite(str(bad / ("m_%d.tif" % k)), np.zeros((8, 9 if k == 2 else 8), np.uint8))
    j = job([str(bad)])
    j.run()
    status, level, message = j.outcome()
    assert (status, level) == ('CANCELLED', 'ERROR') and "m_2.tif" in message
    j = job([str(bad)])
    j.start()   # the open runs on the library's thread: its error comes with the result
    while not j.poll():
        pass
    assert j.outcome()[:2] == ('CANCELLED', 'ERROR') and "m_2.tif" in j.outcome()[2]


@pytest.fixture(scope="module")
def two_series(tmp_path_factory):
    """A folder holding two DICOM series written with pydicom: a CT ball in
    Hounsfield units (stored + 1024, 12 bits, rescaled) on tilted axes and
    a small MR of the same ball."""
    pydicom = pytest.importorskip("pydicom")
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid
    folder = tmp_path_factory.mktemp("dicom") / "two"
    folder.mkdir()
    z, y, x = np.meshgrid(np.arange(10.0), np.arange(12.0), np.arange(14.0), indexing="ij")
    ball = np.sqrt((x - 6.5) ** 2 + (y - 5.5) ** 2 + (z - 4.5) ** 2) < 4.0
    uids = {}
    c, s = np.cos(np.radians(20)), np.sin(np.radians(20))
    for modality, sop, stored, row, col in (
            ("CT", "1.2.840.10008.5.1.4.1.1.2", np.where(ball, 1024 + 700, 1024 - 1000), (c, s, 0), (-s, c, 0)),
            ("MR", "1.2.840.10008.5.1.4.1.1.4", np.where(ball, 900, 100), (1, 0, 0), (0, 1, 0))):
        uids[modality] = series_uid = generate_uid()
        study, frame = generate_uid(), generate_uid()
        normal = np.cross(row, col)
        for k in range(stored.shape[0]):
            ds = Dataset()
            ds.SOPClassUID, ds.SOPInstanceUID = sop, generate_uid()
            ds.StudyInstanceUID, ds.SeriesInstanceUID, ds.FrameOfReferenceUID = study, series_uid, frame
            ds.Modality, ds.SeriesNumber, ds.InstanceNumber = modality, 3 if modality == "CT" else 7, k + 1
            ds.SeriesDescription = "ball " + modality
            ds.PatientName, ds.PatientID = "Phantom^Isomend", "ISOMEND-TEST"
            ds.ImagePositionPatient = ["%.6g" % v for v in np.array((-5.0, -6.0, 20.0)) + 1.5 * k * normal]
            ds.ImageOrientationPatient = ["%.6g" % v for v in list(row) + list(col)]
            ds.PixelSpacing, ds.SliceThickness = ["0.8", "0.7"], "1.5"
            if modality == "CT":
                ds.RescaleSlope, ds.RescaleIntercept, ds.RescaleType = "1", "-1024", "HU"
            ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
            ds.Rows, ds.Columns = stored.shape[1], stored.shape[2]
            ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 12, 11, 0
            ds.PixelData = stored[k].astype("<u2").tobytes()
            meta = FileMetaDataset()
            meta.MediaStorageSOPClassUID, meta.MediaStorageSOPInstanceUID = ds.SOPClassUID, ds.SOPInstanceUID
            meta.TransferSyntaxUID = ExplicitVRLittleEndian
            ds.file_meta, ds.is_little_endian, ds.is_implicit_VR = meta, True, False
            ds.preamble = b"\0" * 128
            pydicom.dcmwrite(str(folder / ("%s%03d.dcm" % (modality, k))), ds, write_like_original=False)
    return {"folder": str(folder), "uids": uids}


def test_a_dicom_series_is_chosen_placed_and_reported(two_series):
    folder, uids = two_series["folder"], two_series["uids"]
    j = job([folder])       # two series and none chosen: an error listing them
    j.run()
    status, level, message = j.outcome()
    assert (status, level) == ('CANCELLED', 'ERROR') and "2 DICOM series" in message
    meshes = []
    for grid_axes in (False, True):
        j = import_stack.ImportJob([folder], None, "dmc", None, -1, True, True,
                                   series=uids["CT"], grid_axes=grid_axes)
        j.run()
        assert j.error is None, j.error
        mesh, info = j.result
        assert info["kind"] == "dicom" and info["dims"] == (14, 12, 10)
        assert mesh.iso == 300.0          # a CT in HU: the bone level is the suggestion
        props = import_stack.custom_properties(mesh, info)
        assert props["isomend_dicom_series_uid"] == uids["CT"]
        assert props["isomend_dicom_axes"] == ("grid" if grid_axes else "patient")
        text = import_stack.report("two", mesh, info, suggested=True)
        assert 'DICOM CT series "ball CT", %s axes (bone level, HU)' % props["isomend_dicom_axes"] in text
        want = isomend.extract_source([folder], pad=True, series=uids["CT"], grid_axes=grid_axes)
        same(mesh, want)
        meshes.append(mesh)
    # the tilted series: patient space turns it (the same triangles elsewhere)
    assert meshes[0].triangle_count == meshes[1].triangle_count
    assert not np.allclose(meshes[0].positions, meshes[1].positions, atol=0.1)
    # post-processing of a mesh in patient space (issue 37): the steps run on
    # the grid-frame C mesh and the result is mapped again, so smoothing and
    # decimating the patient-space mesh and the grid-axes mesh give the same
    # triangles, placed as their inputs are
    post = [isomend.postprocess(mm, smooth=3, decimate=0.5) for mm in meshes]
    np.testing.assert_array_equal(post[0].triangles, post[1].triangles)
    for mm, pp in zip(meshes, post):
        assert pp.check()["hole_edges"] == 0 and pp.triangle_count < 0.6 * mm.triangle_count
        assert np.allclose(pp.positions.mean(0), mm.positions.mean(0), atol=0.5)
        assert pp.grid_box == mm.grid_box
    # the other series, by its UID, and an explicit iso with it
    j = import_stack.ImportJob([folder], 500.0, "dmc", None, -1, True, True, series=uids["MR"])
    j.run()
    mesh, info = j.result
    assert mesh.iso == 500.0 and info["dicom"]["modality"] == "MR" and info["dims"] == (14, 12, 10)
    assert "(bone level" not in import_stack.report("two", mesh, info, suggested=False)
    # a TIFF stack has no DICOM properties
    assert not any(k.startswith("isomend_dicom") for k in
                   import_stack.custom_properties(mesh, dict(info, dicom=None)))


@pytest.fixture(scope="module")
def uneven_ct(tmp_path_factory):
    """Issue 34: an axial CT series of a ball (pydicom) whose slice spacing
    changes part-way, 1.5 mm then 2.5 mm: once refused, now meshed at the
    slices' true positions."""
    pydicom = pytest.importorskip("pydicom")
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid
    folder = tmp_path_factory.mktemp("dicom") / "uneven"
    folder.mkdir()
    z, y, x = np.meshgrid(np.arange(10.0), np.arange(12.0), np.arange(14.0), indexing="ij")
    hu = np.where(np.sqrt((x - 6.5) ** 2 + (y - 5.5) ** 2 + (z - 4.5) ** 2) < 4.0, 700, -1000)
    steps = np.concatenate([[0.0], np.cumsum(np.where(np.arange(9) < 4, 1.5, 2.5))])
    positions = [float("%.6g" % (20.0 + v)) for v in steps]     # as the files say them
    series, study, frame = generate_uid(), generate_uid(), generate_uid()
    for k in range(hu.shape[0]):
        ds = Dataset()
        ds.SOPClassUID, ds.SOPInstanceUID = "1.2.840.10008.5.1.4.1.1.2", generate_uid()
        ds.StudyInstanceUID, ds.SeriesInstanceUID, ds.FrameOfReferenceUID = study, series, frame
        ds.Modality, ds.SeriesNumber, ds.InstanceNumber = "CT", 1, 10 - k
        ds.SeriesDescription = "uneven ball"
        ds.PatientName, ds.PatientID = "Phantom^Isomend", "ISOMEND-TEST"
        ds.ImagePositionPatient = ["-5", "-6", "%.6g" % positions[k]]
        ds.ImageOrientationPatient = ["1", "0", "0", "0", "1", "0"]
        ds.PixelSpacing, ds.SliceThickness = ["0.8", "0.7"], "1.5"
        ds.RescaleSlope, ds.RescaleIntercept, ds.RescaleType = "1", "-1024", "HU"
        ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
        ds.Rows, ds.Columns = hu.shape[1], hu.shape[2]
        ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 12, 11, 0
        ds.PixelData = (hu[k] + 1024).astype("<u2").tobytes()
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID, meta.MediaStorageSOPInstanceUID = ds.SOPClassUID, ds.SOPInstanceUID
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        ds.file_meta, ds.is_little_endian, ds.is_implicit_VR = meta, True, False
        ds.preamble = b"\0" * 128
        pydicom.dcmwrite(str(folder / ("IMG%03d.dcm" % (7 * k % 10))), ds, write_like_original=False)
    return {"folder": str(folder), "hu": hu.astype(np.int16), "positions": positions}


def test_an_unevenly_spaced_dicom_series_is_meshed_where_its_slices_are(uneven_ct):
    j = job([uneven_ct["folder"]])          # suggested: the bone level of a CT
    j.run()
    assert j.error is None and j.outcome() == ('FINISHED', None, None), j.error
    mesh, info = j.result
    geo = info["geometry"]
    assert not geo["uniform"] and geo["warning"], geo
    assert geo["gap_min"] == pytest.approx(1.5) and geo["gap_max"] == pytest.approx(2.5)
    assert geo["uneven_gaps"] > 0 and geo["tilt_degrees"] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_array_equal(info["slice_origins"][:, 2], uneven_ct["positions"])
    # the core's mesh of the same samples at the same positions (the axial
    # series' frame is patient space: x, y from Image Position, no transform)
    want = isomend.extract(uneven_ct["hu"], 300.0, pad=True, spacing=(0.7, 0.8, 1.0),
                           origin=(-5.0, -6.0, 0.0), slice_positions=uneven_ct["positions"])
    same(mesh, want)
    assert mesh.volume_origin == (-5.0, -6.0, uneven_ct["positions"][0])
    # the surface touches no border slice: its z lies strictly between them
    zs = mesh.positions[:, 2]
    assert uneven_ct["positions"][0] < zs.min() and zs.max() < uneven_ct["positions"][-1]
    text = import_stack.report("uneven", mesh, info, suggested=True)
    assert "; slices not evenly spaced (gaps 1.5 to 2.5 mm), meshed at their positions" in text
    warning = import_stack.geometry_warning("uneven", info)
    assert warning == "uneven: " + geo["warning"]
    # the same through the library's thread (the operator's modal path)
    j = job([uneven_ct["folder"]])
    j.start()
    while not j.poll():
        pass
    same(j.result[0], want)
    assert j.result[1]["geometry"] == geo


def test_the_geometry_text_says_only_what_differs():
    even = {"geometry": {"uniform": True, "gap_min": 1.0, "gap_max": 1.0, "tilt_degrees": 0.0,
                         "warning": ""}}
    assert import_stack.geometry_text(even) == "" and import_stack.geometry_warning("a", even) == ""
    assert import_stack.geometry_text({}) == "" and import_stack.geometry_warning("a", {}) == ""
    tilted = {"geometry": {"uniform": False, "gap_min": 1.25, "gap_max": 1.25, "tilt_degrees": 15.0,
                           "warning": "the slices are sheared by a 15 degree gantry tilt"}}
    assert (import_stack.geometry_text(tilted)
            == "slices not evenly spaced (gaps 1.25 to 1.25 mm, tilt 15 degrees), meshed at their positions")
    assert (import_stack.geometry_warning("head", tilted)
            == "head: the slices are sheared by a 15 degree gantry tilt")


# ------------------------------------------------------------ the mesh

def test_mesh_buffers_are_relative_to_the_origin_scaled_and_typed(blob):
    with isomend.open_source(blob["folder"], spacing=(0.5, 0.5, 2.0), origin=(10.0, -20.0, 30.0)) as src:
        mesh = src.extract(iso=250.0, pad=True)
    b = import_stack.mesh_buffers(mesh, 0.001)
    assert b.coords.dtype == np.float32 and b.coords.shape == (3 * mesh.vertex_count,)
    assert b.loop_vertices.dtype == np.int32 and b.loop_starts.dtype == np.int32
    assert b.loop_totals.dtype == np.int32 and set(b.loop_totals) == {3}
    np.testing.assert_array_equal(b.loop_vertices, mesh.triangles.reshape(-1).astype(np.int32))
    np.testing.assert_array_equal(b.loop_starts, 3 * np.arange(mesh.triangle_count))
    assert b.location == pytest.approx((0.010, -0.020, 0.030))
    world = b.coords.reshape(-1, 3).astype(np.float64) + np.array(b.location)
    np.testing.assert_allclose(world, mesh.positions * 0.001, rtol=1e-5, atol=1e-7)
    assert b.normals is mesh.normals and b.normals.shape == (mesh.vertex_count, 3)
    props = import_stack.custom_properties(mesh, {"spacing": (0.5, 0.5, 2.0)})
    assert props == {"isomend_iso": 250.0, "isomend_method": "dmc",
                     "isomend_mending_triangles": mesh.stats["mending_triangles"],
                     "isomend_spacing_mm": [0.5, 0.5, 2.0]}


def test_report_names_the_object_counts_iso_and_spacing(blob):
    j = job([blob["folder"]])
    j.run()
    mesh, info = j.result
    text = import_stack.report("knee_scan", mesh, info, suggested=True)
    assert text.startswith("Imported knee_scan: %d vertices, %d triangles"
                           % (mesh.vertex_count, mesh.triangle_count))
    assert "iso %g (suggested)" % mesh.iso in text and "16x14x12 samples" in text
    assert "(suggested)" not in import_stack.report("x", mesh, info, suggested=False)
    # evenly spaced slices: nothing said about them, no warning
    assert info["geometry"]["uniform"] and info["slice_origins"] is None
    assert "evenly" not in text and import_stack.geometry_warning("knee_scan", info) == ""


def test_post_processing_runs_in_the_clis_order_and_is_reported(blob):
    """Minimum Component, Smooth Iterations, Decimate Ratio (issue 37): run()
    and start()/poll() give isomend.postprocess's mesh, the stage is seen, and
    the report says what each step did."""
    kw = dict(decimate=0.2, smooth_iterations=5, min_component=10)
    j = import_stack.ImportJob([blob["folder"]], 250.0, "dmc", None, -1, True, True, **kw)
    stages = []
    j.printer = lambda stage, fraction: stages.append(stage)
    j.run()
    assert j.error is None, j.error
    mesh, info = j.result
    plain = isomend.extract_source(blob["folder"], iso=250.0, pad=True)
    want = isomend.postprocess(plain, decimate=0.2, smooth=5, min_component=10)
    same(mesh, want)
    assert "postprocess" in stages
    assert abs(mesh.triangle_count - 0.2 * plain.triangle_count) <= 0.02 * plain.triangle_count
    ck = mesh.check()
    assert ck["hole_edges"] == 0 and ck["nonmanifold_edges"] == 0
    d = mesh.postprocess["decimate"]
    text = import_stack.report("knee_scan", mesh, info, suggested=False)
    assert "%d vertices, %d triangles" % (mesh.vertex_count, mesh.triangle_count) in text
    assert ("decimated: %d -> %d triangles (target %d reached), largest error"
            % (d["triangles_before"], d["triangles_after"], d["target_triangles"])) in text
    assert "smoothed: %d vertices moved" % mesh.postprocess["smooth"]["moved_vertices"] in text
    assert "clean-up: " in text
    # on the library's thread: the same
    j2 = import_stack.ImportJob([blob["folder"]], 250.0, "dmc", None, -1, True, True, **kw)
    j2.start()
    while not j2.poll():
        pass
    assert j2.outcome()[0] == 'FINISHED'
    same(j2.result[0], want)
    # off by default: no post-processing text
    j3 = job([blob["folder"]], iso=250.0)
    j3.run()
    assert j3.result[0].postprocess["decimate"] is None
    assert import_stack.postprocess_text(j3.result[0]) == ""
    # a bad value is refused when the job is made (the operator reports it)
    with pytest.raises(ValueError, match="ratio"):
        import_stack.ImportJob([blob["folder"]], 250.0, "dmc", None, -1, True, True, decimate=1.5)


# ------------------------------------------------------------ can the libraries load?

def test_library_check_refuses_a_package_built_for_a_newer_glibc(tmp_path):
    info = tmp_path / "build-info.json"
    info.write_text(json.dumps({"glibc": "2.41"}))
    problem = import_stack.library_problem(str(info), glibc="2.36")
    assert "need glibc 2.41 or newer" in problem and "this system has glibc 2.36" in problem
    assert import_stack.library_problem(str(info), glibc="2.41") is None
    assert import_stack.library_problem(str(info), glibc="2.100") is None   # numeric, not text
    info.write_text("{not json")
    assert "unreadable" in import_stack.library_problem(str(info), glibc="2.36")
    # the package itself loads here
    assert import_stack.library_problem() is None


def test_the_staged_package_records_what_it_needs():
    path = import_stack.BUILD_INFO
    if not os.path.exists(path):
        pytest.skip("the add-on carries the system's libraries (ISOMEND_ADDON_PORTABLE=OFF)")
    with open(path) as fp:
        info = json.load(fp)
    have = import_stack.system_glibc()
    assert import_stack._version_tuple(info["glibc"]) <= import_stack._version_tuple(have)


# ------------------------------------------------------------ one source, two package formats

def test_bl_info_and_the_extension_manifest_agree():
    import ast
    import tomllib
    tree = ast.parse(open(os.path.join(STAGE, "__init__.py")).read())
    bl_info = next(ast.literal_eval(node.value) for node in tree.body
                   if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "bl_info")
    with open(os.path.join(STAGE, "blender_manifest.toml"), "rb") as fp:
        manifest = tomllib.load(fp)
    assert manifest["id"] == os.path.basename(STAGE.rstrip("/")) == "isomend_import"
    assert manifest["version"] == ".".join(map(str, bl_info["version"])) == isomend.version()
    assert manifest["name"] == bl_info["name"] and manifest["type"] == "add-on"
    assert bl_info["blender"] == (3, 4, 0) and manifest["blender_version_min"] == "4.2.0"
    assert manifest["platforms"] == ["linux-x64"]
    assert set(manifest["permissions"]) == {"files"}


# ------------------------------------------------------------ label maps (issue 36)

def test_label_collection_name_drops_a_segmentation_s_inner_extension():
    assert import_stack.label_collection_name(["/d/organs.seg.nrrd"]) == "organs"
    assert import_stack.label_collection_name(["/d/seg.nii.gz"]) == "seg"
    assert import_stack.label_collection_name(["/d/aseg.nrrd"]) == "aseg"
    assert import_stack.label_collection_name(["/d/.seg.nrrd"]) == ".seg"


def test_srgb_to_linear_is_blender_s_conversion():
    assert import_stack.srgb_to_linear((0, 255, 10)) == (0.0, 1.0, 10 / 255 / 12.92, 1.0)
    r = import_stack.srgb_to_linear((128, 0, 0))[0]
    assert abs(r - 0.2158605) < 1e-6  # Blender shows sRGB 128 as linear 0.216


def test_label_job_refuses_what_does_not_apply_and_runs_synchronously(tmp_path):
    with pytest.raises(ValueError, match="does not apply to a label map"):
        import_stack.ImportJob(["x.nii"], None, "dmc", None, -1, True, True, labels="all",
                               decimate=0.5)
    with pytest.raises(ValueError, match="only for a Label Map"):
        import_stack.ImportJob(["x.nii"], None, "dmc", None, -1, True, True, label_table="t.txt")
    job = import_stack.ImportJob(["x.nii"], None, "dmc", None, -1, True, True, labels="all")
    with pytest.raises(ValueError, match="run\\(\\)"):
        job.start()
    v = np.zeros((6, 7, 8), np.uint8)
    v[1:4, 2:5, 2:6] = 3
    path = tmp_path / "one.nrrd"
    path.write_bytes(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 8 7 6\nencoding: raw\n\n"
                     + v.tobytes())
    job = import_stack.ImportJob([str(path)], None, "dmc", None, -1, True, True, labels="all")
    job.run()
    assert job.error is None and job.outcome()[0] == "FINISHED"
    meshes, info = job.result
    assert list(meshes) == [3] and meshes[3].name == "label_3" and info["names_from"] is None
    assert "1 label (3 label_3: %d triangles)" % meshes[3].triangle_count in \
        import_stack.label_report("one", meshes, info)
    job = import_stack.ImportJob([str(path)], None, "dmc", None, -1, True, True, labels="4")
    job.run()
    assert job.outcome()[:2] == ("CANCELLED", "ERROR") and "label 4 is not in" in str(job.error)
