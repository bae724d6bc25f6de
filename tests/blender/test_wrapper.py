"""pytest tests of the bpy-free ctypes wrapper blender_addon/isomend_import/isomend.py.

Run by ctest (tests/blender/CMakeLists.txt) with Debian's python3-pytest:
    ISOMEND_STAGE=<build>/blender_addon/isomend_import ISOMEND_ABI_DUMP=<exe> python3 -m pytest -q test_wrapper.py
ISOMEND_STAGE is the staged add-on folder (isomend.py + lib/) that the build
zips, so these tests load the libraries the way the add-on does ("lib/ next
to the module").  ISOMEND_ABI_DUMP is tests/blender/abi_dump.c compiled
against the headers.
"""
import ctypes
import json
import os
import subprocess
import sys

import numpy as np
import pytest

STAGE = os.environ.get("ISOMEND_STAGE")
if not STAGE:
    pytest.exit("ISOMEND_STAGE is not set (the staged add-on folder)", returncode=2)
sys.path.insert(0, STAGE)
os.environ.pop("ISOMEND_LIB_DIR", None)  # test the add-on's own lookup
import isomend  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
import label_volumes  # noqa: E402


# ------------------------------------------------------------ helpers

def sphere(n=24, r=7.5, centre=(11.3, 12.1, 10.7), dtype=np.float32):
    """array[z, y, x] = r - distance: positive (inside) in a ball."""
    i = np.arange(n, dtype=np.float64)
    z, y, x = np.meshgrid(i, i, i, indexing="ij")
    d = np.sqrt((x - centre[0]) ** 2 + (y - centre[1]) ** 2 + (z - centre[2]) ** 2)
    return (r - d).astype(dtype)


def f1_volume():
    """The thesis's F1(x,y,z) = 4y + 4(x-z)^2 - 5 on {0..3}^3, array[z, y, x]."""
    i = np.arange(4, dtype=np.float64)
    z, y, x = np.meshgrid(i, i, i, indexing="ij")
    return 4 * y + 4 * (x - z) ** 2 - 5


def signed_volume(positions, triangles):
    p = positions.astype(np.float64)[triangles.astype(np.int64)]
    return np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0


def same_mesh(a, b):
    assert a.vertex_count == b.vertex_count
    assert a.triangle_count == b.triangle_count
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.triangles, b.triangles)


# ------------------------------------------------------------ ABI and loading

def test_struct_layouts_and_constants_match_the_headers():
    exe = os.environ.get("ISOMEND_ABI_DUMP")
    if not exe:
        pytest.skip("ISOMEND_ABI_DUMP not set")
    abi = json.loads(subprocess.run([exe], check=True, capture_output=True, text=True).stdout)
    for name, want in abi["structs"].items():
        cls = getattr(isomend, name)
        assert ctypes.sizeof(cls) == want["size"], name
        got = {f: getattr(cls, f).offset for f, _ in cls._fields_}
        assert got == want["offsets"], name
    c = abi["constants"]
    assert isomend.ERR_CANCELLED == c["ISOMEND_ERR_CANCELLED"]
    assert (isomend.TYPE_U8, isomend.TYPE_I8, isomend.TYPE_U16, isomend.TYPE_I16, isomend.TYPE_I32,
            isomend.TYPE_F32, isomend.TYPE_F64) == tuple(
        c["ISOMEND_" + t] for t in ("U8", "I8", "U16", "I16", "I32", "F32", "F64"))
    assert isomend.TYPE_U32 == c["ISOMEND_U32"]
    assert isomend.METHODS["mc"] == c["ISOMEND_METHOD_MC"]
    assert isomend.METHODS["durst"] == c["ISOMEND_METHOD_DURST"]
    assert isomend.METHODS["dmc"] == c["ISOMEND_METHOD_DMC"]
    assert isomend.METHOD_COUNT == c["ISOMEND_METHOD_COUNT"]
    assert isomend.FLAG_NO_NORMALS == c["ISOMEND_FLAG_NO_NORMALS"]
    assert isomend.FLAG_FLIP == c["ISOMEND_FLAG_FLIP"]
    assert isomend.FLAG_PAD == c["ISOMEND_FLAG_PAD"]
    assert isomend.FLAG_NO_ORIGINS == c["ISOMEND_FLAG_NO_ORIGINS"]
    assert isomend.FLAG_SMALL_PAGES == c["ISOMEND_FLAG_SMALL_PAGES"]
    assert (isomend.ORIGIN_TABLE, isomend.ORIGIN_DURST, isomend.ORIGIN_MEND) == (
        c["ISOMEND_ORIGIN_TABLE"], c["ISOMEND_ORIGIN_DURST"], c["ISOMEND_ORIGIN_MEND"])
    assert isomend.IO_ERR_CANCELLED == c["ISOMEND_IO_ERR_CANCELLED"]
    assert max(isomend.IO_STATUS_NAMES) == c["ISOMEND_IO_ERR_SERIES"]
    assert isomend.IO_STATUS_NAMES[c["ISOMEND_IO_ERR_SERIES"]] == "SERIES"
    assert (isomend.IO_AXES_PATIENT, isomend.IO_AXES_GRID) == (
        c["ISOMEND_IO_AXES_PATIENT"], c["ISOMEND_IO_AXES_GRID"])
    for k, level in enumerate(("OTSU", "BONE", "SKIN")):
        assert c["ISOMEND_IO_LEVEL_" + level] == k and isomend.IO_LEVEL_NAMES[k] == level.lower()
    assert (isomend.IO_CHANNEL_AUTO, isomend.IO_CHANNEL_LUMA) == (
        c["ISOMEND_IO_CHANNEL_AUTO"], c["ISOMEND_IO_CHANNEL_LUMA"])
    for k, stage in enumerate(("OPEN", "READ", "ANALYSE", "EXTRACT")):
        assert c["ISOMEND_IO_STAGE_" + stage] == k
        assert isomend.IO_STAGES[k] == stage.lower()
    assert len(isomend.IO_KIND_NAMES) == c["ISOMEND_IO_KIND_DICOM"] + 1
    assert isomend.IO_HISTOGRAM_BINS == c["ISOMEND_IO_HISTOGRAM_BINS"]


def test_libraries_load_from_lib_next_to_the_module():
    lib_dir = os.path.join(STAGE, "lib")
    assert os.path.dirname(isomend.library_path()) == lib_dir
    assert os.path.dirname(isomend.io_library_path()) == lib_dir
    assert isomend.version() == isomend.io_version()
    # every status code the wrapper names has a text in the library
    for status in isomend.STATUS_NAMES:
        assert isomend._status_text(status)


def _run_python(code, env):
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=60)


def test_env_var_overrides_the_library_path(tmp_path):
    env = dict(os.environ, PYTHONPATH=STAGE, PYTHONDONTWRITEBYTECODE="1")
    # a folder without the library: a clear error naming the variable, no fallback
    env["ISOMEND_LIB_DIR"] = str(tmp_path)
    r = _run_python("import isomend; isomend.version()", env)
    assert r.returncode != 0
    assert "ISOMEND_LIB_DIR=" + str(tmp_path) in r.stderr and "LibraryNotFound" in r.stderr
    # a folder list: both libraries found there
    other = tmp_path / "copy"
    other.mkdir()
    for name in os.listdir(os.path.join(STAGE, "lib")):
        with open(os.path.join(STAGE, "lib", name), "rb") as src, open(other / name, "wb") as dst:
            dst.write(src.read())
    env["ISOMEND_LIB_DIR"] = str(tmp_path / "empty") + os.pathsep + str(other)
    r = _run_python("import isomend; print(isomend.library_path()); print(isomend.io_library_path())", env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [str(other / "libisomend.so.0"), str(other / "libisomend_io.so.0")]


def test_methods_list_names_the_three_thesis_methods_first():
    names = [n for n, _ in isomend.methods()]
    assert names[:3] == ["mc", "durst", "dmc"]
    assert {"mc", "durst", "dmc"} <= set(isomend.available_methods())


# ------------------------------------------------------------ extraction

def test_padded_sphere_is_closed_outward_and_the_right_size():
    vol = sphere()
    m = isomend.extract(vol, 0.0, pad=True)
    assert m.stats["vertices"] == m.vertex_count and m.stats["triangles"] == m.triangle_count
    assert m.positions.dtype == np.float32 and m.positions.shape == (m.vertex_count, 3)
    assert m.triangles.dtype == np.uint32 and m.triangles.shape == (m.triangle_count, 3)
    assert m.triangles.max() < m.vertex_count
    rep = m.check()
    assert rep["hole_edges"] == 0 and rep["nonmanifold_edges"] == 0
    assert rep["misoriented_edges"] == 0 and rep["border_edges"] == 0
    assert rep["components"] == 1 and rep["euler"] == 2
    vol_mesh = signed_volume(m.positions, m.triangles)
    assert vol_mesh == pytest.approx(4 / 3 * np.pi * 7.5 ** 3, rel=0.03)  # positive: outward
    # gradient normals: unit length, pointing away from the centre (towards lower values)
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-4)
    radial = m.positions - np.array([11.3, 12.1, 10.7], np.float32)
    assert (np.einsum("ij,ij->i", radial, m.normals) > 0).all()
    # origins: every triangle from the table or a mending quad, counts as in stats
    counts = np.bincount(m.origins, minlength=3)
    assert list(counts) == [m.stats["triangles_by_origin"][k] for k in isomend.ORIGIN_NAMES]


def test_flip_reverses_winding_and_normals():
    vol = sphere()
    a = isomend.extract(vol, 0.0, pad=True)
    b = isomend.extract(vol, 0.0, pad=True, flip=True)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_allclose(a.normals, -b.normals)
    assert signed_volume(b.positions, b.triangles) == pytest.approx(-signed_volume(a.positions, a.triangles))


def test_f1_methods_mc_leaves_holes_dmc_mends_them_durst_adds_polygons():
    vol = f1_volume()
    mc = isomend.extract(vol, 0.0, method="mc")
    dmc = isomend.extract(vol, 0.0, method="dmc")
    durst = isomend.extract(vol, 0.0, method="DURST")
    assert mc.method == "mc" and dmc.method == "dmc" and durst.method == "durst"
    assert mc.check()["hole_edges"] > 0
    assert dmc.check()["hole_edges"] == 0 and dmc.check()["nonmanifold_edges"] == 0
    assert dmc.stats["mending_triangles"] == 6
    assert int((dmc.origins == isomend.ORIGIN_MEND).sum()) == 6
    assert durst.check()["hole_edges"] == 0
    assert durst.stats["durst_triangles"] > 0
    by_id = isomend.extract(vol, 0.0, method=isomend.METHODS["dmc"])
    same_mesh(by_id, dmc)


def test_every_available_method_runs_by_name_and_closes_a_padded_sphere():
    vol = sphere()
    for name in isomend.available_methods():
        m = isomend.extract(vol, 0.0, method=name, pad=True)
        assert m.method == name and m.triangle_count > 0
        rep = m.check()
        assert rep["hole_edges"] == 0 and rep["border_edges"] == 0, (name, rep)


def test_spacing_and_origin_place_the_mesh_in_world_units():
    vol = sphere()
    a = isomend.extract(vol, 0.0)
    b = isomend.extract(vol, 0.0, spacing=(0.5, 2.0, 3.0), origin=(10, -20, 30))
    np.testing.assert_allclose(b.positions, a.positions * [0.5, 2.0, 3.0] + [10, -20, 30], rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(b.grid_box, (10, -20, 30, 10 + 23 * 0.5, -20 + 23 * 2, 30 + 23 * 3))
    assert b.volume_origin == (10, -20, 30) and b.volume_spacing == (0.5, 2.0, 3.0)
    c = isomend.extract(vol, 0.0, spacing=2.0)
    np.testing.assert_allclose(c.positions, a.positions * 2, rtol=1e-6)


def test_slice_positions_mesh_each_slice_where_it_is():
    """Issue 34: slices that are not evenly spaced (isomend_volume.slice_origins
    through extract(slice_positions=)): the same triangles and vertex order as
    the uniform grid, each vertex moved along z to where its edge lies between
    the two slices' true positions."""
    vol = sphere()
    nz = vol.shape[0]
    gaps = np.where(np.arange(nz - 1) < 9, 1.25, 2.0)   # a spacing change part-way
    gaps[15] = 4.0                                       # and a missing slice
    z = 30.0 + np.concatenate([[0.0], np.cumsum(gaps)])
    a = isomend.extract(vol, 0.0, spacing=(0.5, 2.0, 1.0), origin=(10, -20, 0))
    b = isomend.extract(vol, 0.0, spacing=(0.5, 2.0, 1.0), origin=(10, -20, 0),
                        slice_positions=list(z))         # a temporary: kept alive by extract
    np.testing.assert_array_equal(b.triangles, a.triangles)
    np.testing.assert_array_equal(b.positions[:, :2], a.positions[:, :2])
    index = a.positions[:, 2].astype(np.float64)          # k + t on the uniform grid
    np.testing.assert_allclose(b.positions[:, 2], np.interp(index, np.arange(nz), z), rtol=0, atol=2e-5)
    in_slice = index == np.round(index)                   # edges along x and y
    assert in_slice.sum() > 100
    np.testing.assert_allclose(b.positions[in_slice, 2], z[np.round(index[in_slice]).astype(int)],
                               rtol=1e-7)
    assert b.volume_origin == (10.0, -20.0, z[0])
    np.testing.assert_allclose(np.array(b.grid_box)[[2, 5]], [z[0], z[-1]])
    assert b.check()["hole_edges"] == 0 and b.check()["nonmanifold_edges"] == 0
    lengths = np.linalg.norm(b.normals, axis=1)
    assert np.abs(lengths - 1).max() < 1e-5
    # the normals are the gradients over the true neighbours: not the uniform grid's
    assert np.abs(b.normals - a.normals).max() > 0.05
    # evenly spaced positions are the uniform grid
    even = isomend.extract(vol, 0.0, slice_positions=3.0 + 1.5 * np.arange(nz), pad=True)
    grid = isomend.extract(vol, 0.0, spacing=(1, 1, 1.5), origin=(0, 0, 3.0), pad=True)
    np.testing.assert_array_equal(even.triangles, grid.triangles)
    np.testing.assert_allclose(even.positions, grid.positions, rtol=0, atol=1e-5)
    # refused before anything reaches C
    for bad, words in ((z[:-1], "expected %d values" % nz), (z[::-1], "increase strictly"),
                       (np.where(np.arange(nz) == 4, np.nan, z), "finite"),
                       (np.stack([z, z]), "one z value per slice")):
        with pytest.raises(ValueError, match="slice_positions: .*" + words):
            isomend.extract(vol, 0.0, slice_positions=bad)


@pytest.mark.parametrize("view", ["fortran", "reversed_x", "reversed_z", "sliced", "transposed_xyz"])
def test_strided_views_need_no_copy_and_give_the_same_mesh(view):
    base = sphere(26)
    if view == "fortran":
        arr, axes = np.asfortranarray(base), "zyx"
    elif view == "reversed_x":
        arr, axes = base[:, :, ::-1], "zyx"
    elif view == "reversed_z":
        arr, axes = base[::-1], "zyx"
    elif view == "sliced":
        arr, axes = base[1:-1:2, 2:, ::3], "zyx"
    else:  # array[x, y, z], Fortran order: the same memory as base
        arr, axes = base.transpose(2, 1, 0), "xyz"
        assert arr.flags.f_contiguous
    reference = np.ascontiguousarray(arr)
    if axes == "xyz":
        reference = np.ascontiguousarray(base)
    got = isomend.extract(arr, 0.0, axes=axes)
    want = isomend.extract(reference, 0.0)
    same_mesh(got, want)
    assert got.triangle_count > 0


@pytest.mark.parametrize("dtype", ["u1", "i1", "<u2", ">u2", "i2", "i4", "f4", "f8", "f2", "u4", "i8", "?"])
def test_every_dtype_gives_the_same_surface(dtype):
    ball = sphere(20, r=6.0, centre=(9.5, 9.5, 9.5), dtype=np.float64) > 0
    levels = np.where(ball, 100, 20)
    if dtype == "?":
        arr, iso = ball, 0.5
    else:
        arr, iso = levels.astype(dtype), 60.5
    got = isomend.extract(arr, iso, pad=True)
    want = isomend.extract(levels.astype(np.float64), 60.5, pad=True)
    assert got.triangle_count == want.triangle_count > 0
    np.testing.assert_array_equal(got.triangles, want.triangles)
    if dtype != "?":
        np.testing.assert_allclose(got.positions, want.positions, atol=1e-5)


def test_threads_do_not_change_the_mesh():
    vol = sphere(40, r=14, centre=(19.2, 20.1, 18.7))
    same_mesh(isomend.extract(vol, 0.0, threads=1), isomend.extract(vol, 0.0, threads=2))


def test_small_pages_do_not_change_the_mesh(stack):
    # reserved arrays (130^3 samples) at 1 thread and 2; Source too
    vol = sphere(130, r=50, centre=(64.3, 65.1, 63.7))
    for t in (1, 2):
        same_mesh(isomend.extract(vol, 0.0, threads=t),
                  isomend.extract(vol, 0.0, threads=t, small_pages=True))
    same_mesh(isomend.extract_source(stack["folder"], iso=300.0),
              isomend.extract_source(stack["folder"], iso=300.0, small_pages=True))


def test_concurrent_calls_from_python_threads_agree():
    # ctypes releases the GIL: two extractions run at once on the same array
    import threading
    vol = sphere(40, r=14, centre=(19.2, 20.1, 18.7))
    want = isomend.extract(vol, 0.0, threads=1)
    results, errors = [None] * 4, []

    def work(i):
        try:
            results[i] = isomend.extract(vol, 0.0, threads=1, method="dmc")
        except Exception as exc:  # reported below
            errors.append(exc)

    workers = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in workers:
        t.start()
    for t in workers:
        t.join()
    assert not errors
    for got in results:
        same_mesh(got, want)


def test_optional_outputs_can_be_switched_off():
    m = isomend.extract(sphere(), 0.0, normals=False, origins=False)
    assert m.normals is None and m.origins is None and m.triangle_count > 0
    empty = isomend.extract(sphere(), 100.0)
    assert empty.vertex_count == 0 and empty.triangle_count == 0
    assert empty.positions.shape == (0, 3) and empty.triangles.shape == (0, 3)


def test_mesh_arrays_are_views_of_the_c_mesh_freed_with_the_last_of_them():
    import gc
    import weakref
    vol = sphere(40, r=14, centre=(19.2, 20.1, 18.7))
    m = isomend.extract(vol, 0.0, threads=1)
    want = {k: getattr(m, k).copy() for k in ("positions", "normals", "triangles", "origins")}
    # no copy: every array is a view whose base holds the C mesh
    owners = set()
    for k in want:
        a = getattr(m, k)
        assert not a.flags.owndata and a.flags.c_contiguous and a.flags.writeable
        owners.add(id(a.base._owner))
    del a
    assert len(owners) == 1
    owner = weakref.ref(m.positions.base._owner)
    kept = m.triangles
    del m
    gc.collect()
    assert owner() is not None  # one array left: the mesh lives on
    # other extractions reuse freed memory; the kept array must not change
    for _ in range(3):
        isomend.extract(vol, 0.0, threads=1)
    np.testing.assert_array_equal(kept, want["triangles"])
    del kept
    gc.collect()
    assert owner() is None  # the last array gone: isomend_mesh_destroy ran
    # the same values as before
    again = isomend.extract(vol, 0.0, threads=2)
    for k, v in want.items():
        np.testing.assert_array_equal(getattr(again, k), v)


def test_bad_arguments_raise_clear_errors():
    vol = sphere()
    with pytest.raises(ValueError, match="method: unknown method 'marching'"):
        isomend.extract(vol, 0.0, method="marching")
    unavailable = [n for n, ok in isomend.methods() if not ok]
    if unavailable:
        with pytest.raises(isomend.IsomendError, match="not implemented in this build"):
            isomend.extract(vol, 0.0, method=unavailable[0])
    with pytest.raises(ValueError, match="3D array"):
        isomend.extract(vol[0], 0.0)
    with pytest.raises(ValueError, match="spacing: y component"):
        isomend.extract(vol, 0.0, spacing=(1, 0, 1))
    with pytest.raises(ValueError, match="spacing: expected 3 numbers"):
        isomend.extract(vol, 0.0, spacing=(1, 1))
    with pytest.raises(ValueError, match="origin"):
        isomend.extract(vol, 0.0, origin=(0, np.inf, 0))
    with pytest.raises(ValueError, match="iso: must be finite"):
        isomend.extract(vol, float("nan"))
    with pytest.raises(ValueError, match="iso: required"):
        isomend.extract(vol, None)
    with pytest.raises(ValueError, match="axes"):
        isomend.extract(vol, 0.0, axes="xxy")
    with pytest.raises(ValueError, match="threads"):
        isomend.extract(vol, 0.0, threads=-1)
    with pytest.raises(TypeError, match="unsupported dtype complex"):
        isomend.extract(vol.astype(np.complex64), 0.0)
    with pytest.raises(isomend.IsomendError) as err:
        isomend.extract(np.zeros((1, 5, 5), np.float32), 0.0)
    assert err.value.status_name == "BAD_DIMENSIONS" and "dimensions" in str(err.value)
    # with padding a dimension of 1 is allowed
    isomend.extract(np.ones((1, 5, 5), np.float32), 0.5, pad=True)


def test_progress_reports_cancels_and_reraises():
    vol = sphere(48, r=18, centre=(23.5, 24.2, 22.9))
    seen = []
    isomend.extract(vol, 0.0, progress=lambda stage, f: seen.append((stage, f)))
    assert seen and all(stage == "extract" and 0.0 <= f <= 1.0 for stage, f in seen)
    assert [f for _, f in seen] == sorted(f for _, f in seen)
    with pytest.raises(isomend.Cancelled) as err:
        isomend.extract(vol, 0.0, progress=lambda stage, f: True)
    assert err.value.status_name == "CANCELLED"

    class Stop(Exception):
        pass

    def boom(stage, f):
        raise Stop("from the callback")

    with pytest.raises(Stop, match="from the callback"):
        isomend.extract(vol, 0.0, progress=boom)


def test_check_finds_holes_in_an_open_mesh():
    # a tetrahedron without its bottom face: three hole edges forming one loop
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 0.3, 1]], np.float32)
    tri = np.array([[0, 1, 3], [1, 2, 3], [2, 0, 3]])
    rep = isomend.check(pos, tri, box=(-1, -1, -1, 2, 2, 2))
    assert rep["hole_edges"] == 3 and rep["hole_loops"] == 1 and rep["triangles"] == 3
    closed = isomend.check(pos, np.vstack([tri, [[0, 2, 1]]]))
    assert closed["hole_edges"] == 0 and closed["border_edges"] == 0 and closed["euler"] == 2
    with pytest.raises(ValueError, match="index out of range"):
        isomend.check(pos, [[0, 1, 4]])
    with pytest.raises(ValueError, match="box"):
        isomend.check(pos, tri, box=(0, 0, 0))


# ------------------------------------------------------------ slice sources

tifffile = pytest.importorskip("tifffile")


@pytest.fixture(scope="module")
def stack(tmp_path_factory):
    """A 16-bit 'blob' volume as 12 slices s_0.tif .. s_11.tif and as one multi-page TIFF."""
    root = tmp_path_factory.mktemp("stack")
    n = 12
    i = np.arange(n, dtype=np.float64)
    z, y, x = np.meshgrid(i, np.arange(14.0), np.arange(16.0), indexing="ij")
    vol = (1000 * np.exp(-((x - 7.5) ** 2 + (y - 6.2) ** 2 + (z - 5.3) ** 2) / 12)).astype(np.uint16)
    folder = root / "blob"
    folder.mkdir()
    for k in range(n):
        tifffile.imwrite(str(folder / ("s_%d.tif" % k)), vol[k])
    tifffile.imwrite(str(root / "blob_multi.tif"), vol)
    return {"root": root, "folder": str(folder), "multi": str(root / "blob_multi.tif"), "volume": vol}


def test_source_reads_a_folder_in_natural_order(stack):
    with isomend.open_source(stack["folder"]) as src:
        assert src.dims == (16, 14, 12) and np.dtype(src.dtype) == np.uint16
        assert src.kind == "folder" and src.format == "tiff"
        assert src.spacing == (1.0, 1.0, 1.0)
        assert os.path.basename(src.slice_path(2)) == "s_2.tif"
        assert os.path.basename(src.slice_path(10)) == "s_10.tif"
        np.testing.assert_array_equal(src.read(), stack["volume"])
        np.testing.assert_array_equal(src.read_slice(10), stack["volume"][10])
        with pytest.raises(IndexError):
            src.read_slice(12)
        summary = src.analyse()
        assert summary["max"] == stack["volume"].max() and summary["samples"] == 16 * 14 * 12
        assert summary["min"] < summary["suggested_iso"] < summary["max"]
    with pytest.raises(ValueError, match="closed"):
        src.read()
    src.close()  # idempotent


def test_source_extract_equals_extract_on_the_read_array(stack):
    with isomend.open_source(stack["multi"], spacing=(0.5, 0.5, 2.0)) as src:
        assert src.kind == "multipage" and src.spacing_sources == ("option",) * 3
        mesh = src.extract(pad=True)                     # suggested iso
        iso = src.analyse()["suggested_iso"]
    assert mesh.iso == iso
    want = isomend.extract(stack["volume"], iso, spacing=(0.5, 0.5, 2.0), pad=True)
    same_mesh(mesh, want)
    assert mesh.check()["hole_edges"] == 0
    from_folder = isomend.extract_source(stack["folder"], iso=iso, spacing=(0.5, 0.5, 2.0), pad=True)
    same_mesh(from_folder, want)
    fixed = isomend.extract_source(stack["folder"], iso=300.0, method="mc")
    assert fixed.iso == 300.0 and fixed.method == "mc"


def test_source_progress_and_cancel(stack):
    stages = []
    isomend.extract_source(stack["folder"], progress=lambda s, f: stages.append(s))
    assert {"read", "extract"} <= set(stages)  # "open" is rate-limited away on small stacks
    assert set(stages) <= set(isomend.IO_STAGES)
    with pytest.raises(isomend.Cancelled) as err:
        isomend.extract_source(stack["folder"], progress=lambda s, f: s == "read")
    assert err.value.status_name == "CANCELLED"
    with pytest.raises(KeyError):
        isomend.extract_source(stack["folder"], progress=lambda s, f: {}["boom"])


def test_extract_job_polls_to_the_same_mesh_without_python_threads(stack):
    import threading
    import time
    want = isomend.extract_source(stack["folder"], spacing=(0.5, 0.5, 2.0), pad=True)
    job = isomend.ExtractJob(stack["folder"], spacing=(0.5, 0.5, 2.0), pad=True)
    seen = []
    while True:
        # the work is on the C library's thread: Python sees only its own
        assert threading.active_count() == 1
        stage, fraction, done = job.poll()
        assert stage in isomend.IO_STAGES and 0.0 <= fraction <= 1.0
        seen.append(stage)
        if done:
            break
        time.sleep(0.001)
    assert [isomend.IO_STAGES.index(s) for s in seen] == sorted(isomend.IO_STAGES.index(s) for s in seen)
    mesh, info = job.result()
    same_mesh(mesh, want)
    assert mesh.iso == want.iso and mesh.volume_spacing == want.volume_spacing == (0.5, 0.5, 2.0)
    assert info["dims"] == (16, 14, 12) and info["dtype"] == "uint16" and info["kind"] == "folder"
    assert info["spacing_sources"] == ("option",) * 3
    with pytest.raises(ValueError, match="already taken"):
        job.result()
    job.close()  # idempotent after result()


def test_extract_job_cancel_errors_and_abandon(stack, tmp_path):
    job = isomend.ExtractJob(stack["folder"], iso=300.0, method="mc")
    job.cancel()
    with pytest.raises(isomend.Cancelled) as err:
        job.result()
    assert err.value.status_name == "CANCELLED" and "cancelled" in str(err.value)
    assert job.poll()[2]
    missing = str(tmp_path / "no_such_folder")
    with pytest.raises(isomend.IsomendError) as err:
        isomend.ExtractJob(missing).result()
    assert err.value.status_name == "NOT_FOUND" and str(err.value).startswith("open: ")
    assert missing in str(err.value)
    # refused before any thread starts
    with pytest.raises(TypeError, match="poll"):
        isomend.ExtractJob(stack["folder"], progress=lambda s, f: False)
    with pytest.raises(ValueError, match="spacing"):
        isomend.ExtractJob(stack["folder"], spacing=(1, 0, 1))
    with pytest.raises(ValueError, match="method"):
        isomend.ExtractJob(stack["folder"], method="no_such_method")
    # dropped while running: cancelled and joined, nothing leaks or crashes
    for _ in range(20):
        isomend.ExtractJob(stack["multi"]).close()
        job = isomend.ExtractJob(stack["multi"])
        del job


def test_a_stack_at_uneven_slice_positions(stack):
    """open_source(slice_positions=) (isomend_io_options.slice_positions): the
    source's geometry says how the slices lie, slice_origins where they are,
    and the mesh is extract()'s at those positions, also through a job."""
    with isomend.open_source(stack["folder"]) as src:
        g = src.geometry
        assert g["uniform"] and g["warning"] == "" and src.slice_origins is None
        assert g["gap_median"] == g["gap_min"] == g["gap_max"] == 1.0
        assert g["long_gaps"] == g["uneven_gaps"] == 0 and g["tilt_degrees"] == 0.0
    steps = np.array([0, 1, 2, 3.4, 4.8, 5.8, 6.8, 7.8, 9.8, 10.8, 11.8, 12.8])
    z = 2.0 + 0.8 * steps       # gaps 0.8, two of 1.12, one of 1.6 (a missing slice?)
    with isomend.open_source(stack["folder"], slice_positions=z) as src:
        g = src.geometry
        assert not g["uniform"]
        assert g["gap_median"] == pytest.approx(0.8) and g["gap_min"] == pytest.approx(0.8)
        assert g["gap_max"] == pytest.approx(1.6)
        assert g["uneven_gaps"] == 3 and g["long_gaps"] == 1 and g["max_offset"] > 0
        assert src.slice_origins.shape == (12, 3)
        np.testing.assert_array_equal(src.slice_origins[:, 2], z)
        np.testing.assert_array_equal(src.slice_origins[:, :2], 0.0)
        mesh = src.extract(iso=300.0, pad=True)
    want = isomend.extract(stack["volume"], 300.0, pad=True, slice_positions=z)
    same_mesh(mesh, want)
    assert mesh.volume_origin == (0.0, 0.0, z[0])
    job = isomend.ExtractJob(stack["folder"], iso=300.0, pad=True, slice_positions=list(z))
    mesh, info = job.result()
    same_mesh(mesh, want)
    assert not info["geometry"]["uniform"]
    np.testing.assert_array_equal(info["slice_origins"][:, 2], z)
    with pytest.raises(ValueError, match="slice_positions: must increase strictly"):
        isomend.open_source(stack["folder"], slice_positions=z[::-1])
    with pytest.raises(isomend.IsomendError):   # 11 positions for 12 slices
        isomend.open_source(stack["folder"], slice_positions=z[:-1])


def test_source_errors_name_the_file_and_the_reason(stack, tmp_path):
    missing = str(tmp_path / "no_such_folder")
    with pytest.raises(isomend.IsomendError) as err:
        isomend.open_source(missing)
    assert err.value.status_name == "NOT_FOUND" and missing in str(err.value)
    bad = tmp_path / "mismatch"
    bad.mkdir()
    for k in range(3):
        tifffile.imwrite(str(bad / ("s_%d.tif" % k)), np.zeros((8, 8 if k != 2 else 9), np.uint8))
    with pytest.raises(isomend.IsomendError) as err:
        isomend.open_source(str(bad))
    assert err.value.status_name == "MISMATCH" and "s_2.tif" in str(err.value)
    with pytest.raises(ValueError, match="channel"):
        isomend.open_source(stack["folder"], channel="red")
    with pytest.raises(ValueError, match="spacing"):
        isomend.open_source(stack["folder"], spacing=(1, -1, 1))
    with pytest.raises(ValueError, match="raw_type"):
        isomend.open_source(stack["multi"], raw_dims=(4, 4, 4))
    with pytest.raises(ValueError, match="paths"):
        isomend.open_source([])


def test_raw_source(stack, tmp_path):
    path = tmp_path / "blob.raw"
    stack["volume"].astype(">u2").tofile(str(path))
    with isomend.open_source(str(path), raw_dims=(16, 14, 12), raw_type="u16", raw_big_endian=True) as src:
        assert src.kind == "raw"
        np.testing.assert_array_equal(src.read(), stack["volume"])


def test_channels_of_an_rgb_stack(tmp_path):
    rng = np.random.default_rng(5)
    rgb = rng.integers(0, 255, (4, 6, 7, 3), dtype=np.uint8)  # z, y, x, channel
    for k in range(4):
        tifffile.imwrite(str(tmp_path / ("c_%d.tif" % k)), rgb[k], photometric="rgb")
    with isomend.open_source(str(tmp_path), channel=1) as src:
        assert src.dims == (7, 6, 4)
        np.testing.assert_array_equal(src.read(), rgb[..., 1])
    with isomend.open_source(str(tmp_path), channel="luma") as src:
        assert np.dtype(src.dtype) == np.float32
        luma = src.read()
    want = rgb.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    assert np.abs(luma - want).max() < 1e-3  # Rec.709 weights, in the samples' own units
    with pytest.raises(isomend.IsomendError) as err:
        isomend.open_source(str(tmp_path))  # channel "auto" with three channels
    assert err.value.status_name == "UNSUPPORTED"
    assert "c_0.tif" in str(err.value) and "channel" in str(err.value)



# ------------------------------------------------------------ post-processing (issue 37)

def sphere_with_speck():
    """A padded sphere plus a one-sample speck far from it: two components,
    the speck's 8 triangles the smaller."""
    vol = sphere(40, r=14, centre=(19.2, 20.1, 18.7))
    vol[3, 3, 3] = 1.0
    return vol


def test_mesh_clean_drops_small_components_and_stays_closed():
    m = isomend.extract(sphere_with_speck(), 0.0, pad=True)
    assert m.check()["components"] == 2
    c, rep = m.clean(min_triangles=20)
    assert set(rep) == {"components_before", "components_after", "triangles_removed",
                        "vertices_removed"}
    assert (rep["components_before"], rep["components_after"]) == (2, 1)
    assert rep["triangles_removed"] == 8 and rep["vertices_removed"] == 6
    assert c.triangle_count == m.triangle_count - 8
    ck = c.check()
    assert ck["components"] == 1 and ck["hole_edges"] == 0 and ck["nonmanifold_edges"] == 0
    assert c.postprocess["clean"] == rep and c.origins is None and c.normals is not None
    # the input is unchanged; keep_largest alone does the same here
    assert m.check()["components"] == 2
    c2, rep2 = m.clean(keep_largest=1)
    assert rep2["components_after"] == 1
    np.testing.assert_array_equal(c2.triangles, c.triangles)


def test_mesh_smooth_keeps_the_volume_and_closure():
    # a binary ball: the voxel staircase that smoothing removes
    ball = np.where(sphere(40, r=14, centre=(19.2, 20.1, 18.7)) > 0, 255, 0).astype(np.uint8)
    m = isomend.extract(ball, 127.5, pad=True)
    s, rep = m.smooth(10)
    assert set(rep) == {"moved_vertices", "volume_before", "volume_after", "max_displacement"}
    assert rep["moved_vertices"] == m.vertex_count  # closed: nothing locked
    assert 0 < rep["max_displacement"] < 1.5
    # the same triangles, vertices moved, the enclosed volume kept
    np.testing.assert_array_equal(s.triangles, m.triangles)
    assert not np.array_equal(s.positions, m.positions)
    v0, v1 = signed_volume(m.positions, m.triangles), signed_volume(s.positions, s.triangles)
    assert abs(v1 - v0) < 1e-3 * abs(v0)
    assert abs(rep["volume_before"] - v0) < 1e-3 * abs(v0)
    ck = s.check()
    assert ck["hole_edges"] == 0 and ck["misoriented_edges"] == 0
    # smoother: the spread of the vertices' distances from the centre shrinks (0.20 -> 0.11)
    centre = np.array([19.2, 20.1, 18.7])
    spread = lambda p: np.std(np.linalg.norm(p.astype(np.float64) - centre, axis=1))
    assert spread(s.positions) < 0.7 * spread(m.positions)
    same, _ = m.smooth(0)
    np.testing.assert_array_equal(same.positions, m.positions)


def test_mesh_decimate_to_a_ratio_a_count_and_an_error():
    m = isomend.extract(sphere(40, r=14, centre=(19.2, 20.1, 18.7)), 0.0, pad=True)
    d, rep = m.decimate(ratio=0.2)
    keys = {"triangles_before", "triangles_after", "vertices_before", "vertices_after",
            "target_triangles", "reached", "max_error", "mean_error", "collapses",
            "locked_vertices", "refused_topology", "refused_geometry", "refused_error"}
    assert set(rep) == keys
    assert rep["reached"] is True and rep["triangles_before"] == m.triangle_count
    assert rep["triangles_after"] == d.triangle_count <= rep["target_triangles"] + 2
    assert abs(d.triangle_count - 0.2 * m.triangle_count) <= 0.01 * m.triangle_count
    ck = d.check()
    assert (ck["hole_edges"], ck["nonmanifold_edges"], ck["misoriented_edges"]) == (0, 0, 0)
    assert ck["euler"] == 2 and ck["components"] == 1
    assert 0 < rep["mean_error"] <= rep["max_error"] < 0.5
    assert d.normals is not None and np.allclose(np.linalg.norm(d.normals, axis=1), 1, atol=1e-4)
    # outward orientation kept
    assert signed_volume(d.positions, d.triangles) > 0
    d2, rep2 = m.decimate(target_triangles=1000)
    assert rep2["target_triangles"] == 1000 and d2.triangle_count <= 1002
    # an error bound: fewer collapses than the ratio's, every one within it
    d3, rep3 = m.decimate(ratio=0.01, max_error=0.05)
    assert rep3["max_error"] <= 0.05 + 1e-9 and rep3["refused_error"] > 0
    assert rep3["reached"] is False and d3.triangle_count > 0.01 * m.triangle_count


def test_extract_postprocesses_in_the_command_lines_order():
    vol = sphere_with_speck()
    e = isomend.extract(vol, 0.0, pad=True, min_component=20, smooth=5, decimate=0.2)
    m = isomend.extract(vol, 0.0, pad=True)
    c, _ = m.clean(20)
    s, _ = c.smooth(5)
    d, _ = s.decimate(ratio=0.2)
    np.testing.assert_array_equal(e.triangles, d.triangles)
    np.testing.assert_array_equal(e.positions, d.positions)
    assert set(e.postprocess) == {"clean", "smooth", "decimate"}
    assert all(e.postprocess[k] is not None for k in e.postprocess)
    assert e.postprocess["clean"]["components_after"] == 1
    assert e.check()["hole_edges"] == 0
    # the extraction's stats stay (mending counts describe the extraction)
    assert e.stats == m.stats
    # a dict of targets; off by default
    t = isomend.extract(vol, 0.0, pad=True, decimate={"target_triangles": 500})
    assert t.postprocess["decimate"]["target_triangles"] == 500 and t.postprocess["clean"] is None
    plain = isomend.extract(vol, 0.0, pad=True, decimate=0)
    assert plain.postprocess == {"clean": None, "smooth": None, "decimate": None}
    assert plain.triangle_count == m.triangle_count and plain.origins is not None
    # largest=1 drops the speck
    assert isomend.extract(vol, 0.0, pad=True, largest=1).check()["components"] == 1


def test_postprocess_refuses_bad_arguments_before_extracting():
    m = isomend.extract(sphere(), 0.0, pad=True)
    with pytest.raises(ValueError, match="ratio"):
        m.decimate(ratio=1.5)
    with pytest.raises(ValueError, match="ratio"):
        m.decimate(ratio=0.0)
    with pytest.raises(ValueError, match="give ratio"):
        m.decimate()
    with pytest.raises(ValueError, match="max_error"):
        m.decimate(max_error=-1)
    with pytest.raises(ValueError, match="iterations"):
        m.smooth(-1)
    with pytest.raises(ValueError, match="iterations"):
        m.smooth(10001)
    with pytest.raises(TypeError, match="min_triangles"):
        m.clean(min_triangles=2.5)
    called = []
    with pytest.raises(ValueError, match="ratio"):
        isomend.extract(sphere(), 0.0, decimate=2.0,
                        progress=lambda *a: called.append(a))
    assert called == []  # refused before the extraction started
    with pytest.raises(ValueError, match="unknown"):
        isomend.extract(sphere(), 0.0, decimate={"ratio": 0.5, "speed": 1})


def test_nifti_source_is_placed_by_its_sform_in_patient_space(tmp_path):
    """A .nii.gz (NIfTI issue 36): kind "nifti", the mesh through the world
    transform, every vertex on an edge of the voxel grid of nibabel's affine
    (RAS) after the LPS flip."""
    nib = pytest.importorskip("nibabel")
    vol = sphere(dtype=np.float32).transpose(2, 1, 0)  # [i, j, k]
    t = np.radians(30)
    A = np.eye(4)
    A[:3, :3] = np.array([[-np.cos(t), -np.sin(t), 0], [-np.sin(t), np.cos(t), 0], [0, 0, 1]]) @ np.diag([0.8, 0.9, 1.2])
    A[:3, 3] = [10.0, -20.0, 5.0]
    img = nib.Nifti1Image(np.ascontiguousarray(vol), A)
    img.header.set_sform(A, code=2)
    path = str(tmp_path / "blob.nii.gz")
    nib.save(img, path)
    with isomend.open_source(path) as src:
        assert src.kind == "nifti" and src.world_transform is not None
        mesh = src.extract(iso=0.0, pad=True)
    assert mesh.check()["hole_edges"] == 0 and len(mesh.positions) > 100
    ras = np.asarray(mesh.positions, float) * [-1, -1, 1]
    ijk = (np.linalg.inv(nib.load(path).affine) @ np.c_[ras, np.ones(len(ras))].T).T[:, :3]
    on_edge = (np.abs(ijk - np.round(ijk)) < 1e-4).sum(axis=1) >= 2
    assert on_edge.all(), ijk[~on_edge][:3]


# ------------------------------------------------------------ label maps

def label_map():
    """Nested shells (labels 1, 4, 5) and a box (7) touching the outer shell."""
    z, y, x = np.indices((15, 16, 18)).astype(float)
    r = np.sqrt((x - 8.2) ** 2 + (y - 7.6) ** 2 + (z - 7.1) ** 2)
    v = np.select([r < 3, r < 5.2, r < 7], [5, 4, 1], 0).astype(np.uint8)
    v[3:12, 3:12, 14:17] = 7
    return v


def test_extract_labels_equals_extract_of_each_indicator():
    v = label_map()
    meshes = isomend.extract_labels(v, spacing=(0.5, 1.0, 2.0), origin=(1, 2, 3), threads=2)
    assert list(meshes) == [1, 4, 5, 7]
    for value, m in meshes.items():
        ref = isomend.extract((v == value).astype(np.uint8), 0.5, spacing=(0.5, 1.0, 2.0),
                              origin=(1, 2, 3), pad=True, threads=1)
        same_mesh(m, ref)
        np.testing.assert_array_equal(m.normals, ref.normals)
        np.testing.assert_array_equal(m.origins, ref.origins)
        assert m.label == value and m.voxels == int((v == value).sum())
        rep = isomend.check(m.positions, m.triangles, box=m.grid_box)
        assert rep["hole_edges"] == 0 and rep["border_edges"] == 0
        assert rep["nonmanifold_edges"] == 0 and rep["misoriented_edges"] == 0


def test_labels_smoothed_and_decimated_together():
    v = label_map()
    meshes = isomend.extract_labels(v)
    def shared(ms):
        """(a, b, position) of the positions two labels' meshes both hold."""
        out = []
        keys = list(ms)
        for i, a in enumerate(keys):
            pa = {tuple(p) for p in ms[a].positions.tolist()}
            for b in keys[i + 1:]:
                out += [(a, b, p) for p in {tuple(p) for p in ms[b].positions.tolist()} & pa]
        return out
    before = shared(meshes)
    assert before
    smoothed, reports = isomend.smooth_labels(meshes, 10)
    for value, m in smoothed.items():
        rep = m.check()
        assert rep["hole_edges"] == rep["border_edges"] == rep["nonmanifold_edges"] == 0
        assert rep["misoriented_edges"] == 0 and rep["euler"] == meshes[value].check()["euler"]
        np.testing.assert_array_equal(m.triangles, meshes[value].triangles)
        assert m.label == value and m.name == meshes[value].name
        assert reports[value]["moved_vertices"] > 0
        assert abs(reports[value]["volume_after"] / reports[value]["volume_before"] - 1) < 0.02
    # the pairs of vertices shared before are shared after: each index's new position
    for a, b, p in before:
        ia = np.flatnonzero((meshes[a].positions == p).all(axis=1))[0]
        ib = np.flatnonzero((meshes[b].positions == p).all(axis=1))[0]
        np.testing.assert_array_equal(smoothed[a].positions[ia], smoothed[b].positions[ib])
    # each label alone (Mesh.smooth) parts them: the test can fail
    alone = {k: m.smooth(10)[0] for k, m in meshes.items()}
    parted = 0
    for a, b, p in before:
        ia = np.flatnonzero((meshes[a].positions == p).all(axis=1))[0]
        ib = np.flatnonzero((meshes[b].positions == p).all(axis=1))[0]
        parted += not np.array_equal(alone[a].positions[ia], alone[b].positions[ib])
    assert parted > 0
    decimated, dreps = isomend.decimate_labels(smoothed, ratio=0.3)
    kept = shared(decimated)
    assert {(a, b, p) for a, b, p in shared(smoothed)} <= set(kept)
    assert sum(m.triangle_count for m in decimated.values()) < sum(m.triangle_count for m in smoothed.values())
    for value, m in decimated.items():
        rep = m.check()
        assert rep["hole_edges"] == rep["border_edges"] == rep["nonmanifold_edges"] == 0
        assert rep["euler"] == meshes[value].check()["euler"]
        assert dreps[value]["triangles_after"] == m.triangle_count
    with pytest.raises(ValueError):
        isomend.smooth_labels(meshes, -1)


def test_extract_labels_types_order_and_errors():
    v = label_map()
    base = isomend.extract_labels(v, labels=[7, 1])
    assert list(base) == [7, 1]
    for arr, labels in [(v.astype(np.uint32) + 4000000000, [4000000007, 4000000001]),
                        (v.astype(np.int64) - 3, [4, -2]), (v.astype(np.float64), [7, 1]),
                        (v.astype(np.int16) * -1, [-7, -1])]:
        got = isomend.extract_labels(arr, labels=labels)
        for (a, ma), (b, mb) in zip(base.items(), got.items()):
            same_mesh(ma, mb)
    # a label that is not there is refused, as the command line and the hosts refuse it
    with pytest.raises(isomend.IsomendError, match="label 9 is not in the volume"):
        isomend.extract_labels(v, labels=[9])
    with pytest.raises(ValueError):
        isomend.extract_labels(v.astype(np.float32) + 0.5)
    with pytest.raises(ValueError):
        isomend.extract_labels(v, labels=[1, 1])
    with pytest.raises(TypeError):
        isomend.extract_labels(v.astype(np.complex64))
    with pytest.raises(isomend.IsomendError):
        isomend.extract_labels(v, method="mc33")


def touching_labels():
    """The host tests' organs (tests/common/label_volumes.py), the ball as label 7."""
    v = label_volumes.organs()
    v[v == 3] = 7
    return v


def test_extract_labels_is_each_indicator_s_surface_byte_for_byte():
    v = touching_labels()
    got = isomend.extract_labels(v, pad=True, spacing=(0.5, 0.6, 1.5), origin=(1, 2, 3))
    assert list(got) == [1, 2, 7]
    for value, mesh in got.items():
        ref = isomend.extract((v == value).astype(np.uint8), 0.5, pad=True,
                              spacing=(0.5, 0.6, 1.5), origin=(1, 2, 3))
        same_mesh(mesh, ref)
        np.testing.assert_array_equal(mesh.normals, ref.normals)
        np.testing.assert_array_equal(mesh.origins, ref.origins)
        assert mesh.label == value and mesh.voxels == int((v == value).sum())
        assert mesh.name == "label_%d" % value and len(mesh.color) == 3
        assert mesh.check()["hole_edges"] == 0 and mesh.check()["nonmanifold_edges"] == 0
        assert mesh.stats["triangles"] == mesh.triangle_count
        assert mesh.volume_origin == (1.0, 2.0, 3.0)
    # touching labels share their boundary's vertex positions
    shared = set(map(tuple, got[1].positions)) & set(map(tuple, got[2].positions))
    assert len(shared) > 50
    # the palette gives distinct colours to these values
    assert len({m.color for m in got.values()}) == 3


def test_extract_labels_dtypes_axes_and_a_list():
    v = touching_labels()
    ref = isomend.extract_labels(v, labels=[7, 2])
    assert list(ref) == [7, 2]
    for dtype in (np.int8, np.uint16, np.int16, np.int32, np.uint32, np.int64, np.uint64,
                  np.float32):
        got = isomend.extract_labels(v.astype(dtype), labels="7,2")
        for value in (2, 7):
            same_mesh(got[value], ref[value])
    # a Fortran-order [x, y, z] view: the same meshes, no copy needed
    got = isomend.extract_labels(np.asfortranarray(v.transpose(2, 1, 0)), labels=7, axes="xyz")
    same_mesh(got[7], ref[7])
    # the meshes outlive the result's other labels and the input
    one = isomend.extract_labels(v.copy(), labels=[1])[1]
    import gc
    gc.collect()
    assert one.check()["hole_edges"] == 0


def test_extract_labels_refuses_bad_input_with_a_message():
    v = touching_labels()
    f = v.astype(np.float32)
    f[3, 4, 5] = 2.5
    with pytest.raises(ValueError, match=r"holds integers; this one has 2.5 at index \(3, 4, 5\)"):
        isomend.extract_labels(f)
    with pytest.raises(ValueError, match="label 2 is listed twice"):
        isomend.extract_labels(v, labels=[2, 1, 2])
    with pytest.raises(TypeError, match="not an integer label"):
        isomend.extract_labels(v, labels=[1, 2.5])
    with pytest.raises(ValueError, match="'all' or integers"):
        isomend.extract_labels(v, labels="1,two")
    with pytest.raises(isomend.IsomendError, match="label 9 is not in the volume"):
        isomend.extract_labels(v, labels=[1, 9])
    with pytest.raises(isomend.IsomendError, match="no label but the background 0"):
        isomend.extract_labels(np.zeros((4, 4, 4), np.uint8))
    with pytest.raises(isomend.IsomendError, match="takes dmc"):
        isomend.extract_labels(v, method="tetra")
    with pytest.raises(ValueError, match="do not fit a 32-bit"):
        isomend.extract_labels(np.full((3, 3, 3), 2**40, np.int64))


def test_extract_labels_names_and_colours_from_a_table(tmp_path):
    table = tmp_path / "lut.txt"
    table.write_text("# FreeSurfer LUT\n1 Left-Cortex 200 10 20 0\n7 Lesion 1 2 3 0\n")
    got = isomend.extract_labels(touching_labels(), label_table=str(table))
    assert [(m.name, m.color) for m in got.values()] == [
        ("Left-Cortex", (200, 10, 20)), ("label_2", got[2].color), ("Lesion", (1, 2, 3))]
    assert got[1].names_from == "slicer/freesurfer"
    with pytest.raises(isomend.IsomendError, match="no_table.txt"):
        isomend.extract_labels(touching_labels(), label_table=str(tmp_path / "no_table.txt"))
    bad = tmp_path / "bad.txt"
    bad.write_text("1 Liver red green blue\n")
    with pytest.raises(isomend.IsomendError, match="line 1"):
        isomend.extract_labels(touching_labels(), label_table=str(bad))


def test_extract_labels_source_seg_nrrd_and_nifti(tmp_path):
    v = touching_labels()
    seg = tmp_path / "organs.seg.nrrd"
    label_volumes.write_seg_nrrd(str(seg), v, (0.5, 0.6, 1.5), label_volumes.SEGMENTS[:2])
    got = isomend.extract_labels_source(str(seg), pad=True)
    ref = isomend.extract_labels(v, pad=True, spacing=(0.5, 0.6, 1.5))
    assert list(got) == [1, 2, 7]
    for value in got:
        same_mesh(got[value], ref[value])
    assert (got[1].name, got[1].color) == ("Liver", (255, 0, 0))
    assert (got[2].name, got[2].color) == ("Left kidney", (0, 128, 255))
    assert got[7].name == "label_7" and got[7].names_from == "seg.nrrd"
    with isomend.open_source(str(seg)) as src:
        two = src.extract_labels(labels=[2], pad=True)
    same_mesh(two[2], ref[2])
    with pytest.raises(isomend.IsomendError, match="label 5 is not in .*organs.seg.nrrd"):
        isomend.extract_labels_source(str(seg), labels=[5])

    nib = pytest.importorskip("nibabel")
    # NIfTI uint32 arrives as f64 and is taken as whole numbers; placed by its affine
    A = np.diag([0.5, 0.6, 1.5, 1.0])
    nii = str(tmp_path / "seg.nii.gz")
    nib.save(nib.Nifti1Image(v.transpose(2, 1, 0).astype(np.uint32), A), nii)
    got = isomend.extract_labels_source(nii, pad=True)
    assert list(got) == [1, 2, 7]
    for value in got:
        # RAS -> LPS: x and y negated
        np.testing.assert_allclose(got[value].positions * [-1, -1, 1], ref[value].positions,
                                   atol=1e-5)
        assert got[value].triangle_count == ref[value].triangle_count
    f = v.astype(np.float32)
    f[4, 5, 6] = 0.25
    nib.save(nib.Nifti1Image(f.transpose(2, 1, 0), A), str(tmp_path / "frac.nii.gz"))
    with pytest.raises(isomend.IsomendError, match=r"non-integer sample 0.25 at \(6, 5, 4\)"):
        isomend.extract_labels_source(str(tmp_path / "frac.nii.gz"))
