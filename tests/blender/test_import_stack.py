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
    order = ["open", "read", "analyse", "extract", "mesh"]
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
