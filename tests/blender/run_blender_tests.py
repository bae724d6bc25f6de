"""Drives the headless Blender test of the add-on (ctest: blender_addon_import).

1. writes slice stacks into a fresh work folder (tifffile): a u8 smoothed
   noise field with many inverted combinations (DMC mends them), a float32 multi-page
   TIFF, the project's real MRI sample (NRRD), and broken stacks;
2. runs the `isomend extract` command line on each good stack with the same
   parameters as the add-on and keeps its JSON (vertex, triangle and mending
   triangle counts);
3. runs Blender in background mode with a fresh user-scripts/config/cache/tmp
   folder (nothing in $HOME), which installs the add-on package, enables it and
   runs blender_import_test.py on those cases;
   with a label map (a 3D Slicer .seg.nrrd of three touching structures),
   compared with `isomend extract --labels all` per label;
4. checks that Blender reported (WARNING) the importer's geometry warning for
   each series whose slices are not evenly spaced (issue 34).

Usage: run_blender_tests.py --blender EXE --package ZIP [--install legacy|extension]
                            --cli isomend --work DIR [--sample samples/anatomical.nrrd]
                            [--get-test-data scripts/get-test-data.sh] [--mode background|gui]
--package is the legacy add-on zip (--install legacy, the default; Blender 3.4+)
or the extension zip (--install extension; Blender 4.2+).  --get-test-data adds
the real MRI of scripts/get-test-data.sh, imported with an explicit iso that
differs from the suggested one (it must win); a failed download fails the test.
--mode gui runs Blender's interface under Xvfb instead (blender_modal_test.py):
the modal import with its worker thread, and Esc cancelling it.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import zipfile

import numpy as np
import tifffile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "common"))
import label_volumes  # noqa: E402


def foam(shape=(30, 34, 38), seed=7):
    """array[z, y, x] u8: random noise smoothed by a 3-tap filter per axis, so
    that many neighbouring cubes form inverted combinations (DMC mends them)."""
    v = np.random.default_rng(seed).random(shape)
    for axis in range(3):
        v = (np.roll(v, 1, axis) + 2 * v + np.roll(v, -1, axis)) / 4
    v = (v - v.min()) / (v.max() - v.min())
    return np.round(255 * v).astype(np.uint8)


def blob(shape=(20, 26, 22)):
    """array[z, y, x] f32: two overlapping Gaussian blobs (a peanut)."""
    z, y, x = np.meshgrid(*(np.arange(n, dtype=np.float64) for n in shape), indexing="ij")
    a = np.exp(-((x - 8) ** 2 + (y - 12) ** 2 + (z - 9) ** 2) / 18)
    b = np.exp(-((x - 14) ** 2 + (y - 13) ** 2 + (z - 10) ** 2) / 14)
    return (a + b).astype(np.float32)


def ply_bbox(path):
    """(min x, y, z, max x, y, z) of a binary little-endian PLY whose vertex
    properties are all float (as `isomend extract` writes them)."""
    with open(path, "rb") as fp:
        data = fp.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert "format binary_little_endian 1.0" in header, header[:3]
    nv, props, in_vertex = 0, 0, False
    for line in header:
        words = line.split()
        if words[:2] == ["element", "vertex"]:
            nv, in_vertex = int(words[2]), True
        elif words[:1] == ["element"]:
            in_vertex = False
        elif words[:1] == ["property"] and in_vertex:
            assert words[1] == "float", line
            props += 1
    v = np.frombuffer(data, dtype="<f4", count=nv * props, offset=end).reshape(nv, props)[:, :3]
    return [float(x) for x in np.concatenate([v.min(0), v.max(0)])]


def run_cli(cli, work, name, source_args, params):
    out_json = os.path.join(work, name + ".cli.json")
    cmd = [cli, "extract", *source_args, "-o", os.path.join(work, name + ".cli.ply"),
           "--method", params["method"].lower(), "--json", out_json, "--quiet"]
    if params.get("pad", True):
        cmd.append("--pad")
    if not params.get("use_suggested_iso", True):
        cmd += ["--iso", repr(params["iso"])]
    if any(params.get("spacing", (0, 0, 0))):
        cmd += ["--spacing", ",".join(repr(float(s)) for s in params["spacing"])]
    if params.get("series"):
        cmd += ["--series", params["series"]]
    if params.get("grid_axes"):
        cmd.append("--grid-axes")
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        sys.exit("isomend CLI failed on %s (%s): %s" % (name, " ".join(cmd), r.stderr.strip()))
    with open(out_json) as fp:
        result = json.load(fp)
    result["bbox"] = ply_bbox(os.path.join(work, name + ".cli.ply"))
    return result


def blender_env(work, tag):
    """A fresh user-scripts/config/cache/tmp folder for one Blender run (nothing in $HOME)."""
    home = os.path.join(work, "blender_home" + tag)
    for sub in ("scripts", "config", "cache", "tmp"):
        os.makedirs(os.path.join(home, sub), exist_ok=True)
    env = dict(os.environ, BLENDER_USER_SCRIPTS=os.path.join(home, "scripts"),
               BLENDER_USER_CONFIG=os.path.join(home, "config"),
               XDG_CACHE_HOME=os.path.join(home, "cache"), TMPDIR=os.path.join(home, "tmp"),
               HOME=home)
    env.pop("ISOMEND_LIB_DIR", None)  # the add-on must use its own lib/
    return env


def refuse(args, work, stack, inner):
    """Two broken copies of the package: one recording that its libraries need
    glibc 99.0, one without its importer library.  Each must install, enable
    and refuse the import with a message naming the reason, printing no
    traceback.  Returns the exit status."""
    variants = [("glibc", "need glibc 99.0 or newer"), ("missing", "libisomend_io")]
    status = 0
    for tag, expect in variants:
        copy = os.path.join(work, "broken_" + tag)
        shutil.copytree(os.path.dirname(inner) if args.install == "legacy" else inner, copy)
        lib = os.path.join(copy, "isomend_import" if args.install == "legacy" else "", "lib")
        if tag == "glibc":
            path = os.path.join(lib, "build-info.json")
            info = json.load(open(path)) if os.path.exists(path) else {}
            info["glibc"] = "99.0"
            json.dump(info, open(path, "w"))
        else:
            os.remove(os.path.join(lib, "libisomend_io.so.0"))
        package = os.path.join(work, "broken_%s.zip" % tag)
        with zipfile.ZipFile(package, "w", zipfile.ZIP_DEFLATED) as zf:
            for root, _, files in os.walk(copy):
                for f in files:
                    full = os.path.join(root, f)
                    zf.write(full, os.path.relpath(full, copy))
        spec = os.path.join(work, "refuse_%s.json" % tag)
        json.dump({"package": package, "install": args.install, "directory": stack, "expect": expect},
                  open(spec, "w"))
        cmd = [args.blender, "-b", "--factory-startup", "-noaudio", "--python-exit-code", "1",
               "--python", os.path.join(HERE, "blender_refuse_test.py"), "--", spec]
        r = subprocess.run(cmd, env=blender_env(work, "_" + tag), capture_output=True, text=True,
                           timeout=300)
        out = r.stdout + r.stderr
        print(out)
        if r.returncode != 0 or "refuse test: passed" not in out:
            print("FAIL: %s: Blender exit %d" % (tag, r.returncode))
            status = 1
        elif "Traceback" in out:
            print("FAIL: %s: a traceback was printed" % tag)
            status = 1
    return status


def real_stack_case(args, work):
    """The real MRI's TIFF folder, the suggested iso and a level halfway
    between it and the maximum (never the suggestion), with the CLI's counts
    for both, padded, DMC."""
    r = subprocess.run(["bash", args.get_test_data, "mri_t1_small"], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit("scripts/get-test-data.sh could not provide the real MRI (exit %d): %s"
                 % (r.returncode, r.stderr.strip()))
    root = os.environ.get("ISOMEND_TESTDATA") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "isomend")
    folder = os.path.join(root, "mri_t1_small", "tiff")
    info = subprocess.run([args.cli, "info", folder, "--json", "-"], capture_output=True, text=True)
    if info.returncode != 0:
        sys.exit("isomend info %s failed: %s" % (folder, info.stderr))
    summary = json.loads(info.stdout.splitlines()[-1])
    suggested = summary["suggested_iso"]
    iso = float(int((suggested + summary["max"]) / 2)) + 0.5
    assert iso != suggested
    base = {"method": "DMC", "pad": True}
    explicit = run_cli(args.cli, work, "real_explicit", [folder], dict(base, use_suggested_iso=False, iso=iso))
    sugg = run_cli(args.cli, work, "real_suggested", [folder], dict(base, use_suggested_iso=True))
    assert sugg["iso"] == suggested, (sugg["iso"], suggested)
    print("real MRI %s: suggested iso %g (%d triangles), explicit iso %g (%d triangles)"
          % (folder, suggested, sugg["triangles"], iso, explicit["triangles"]))
    return {"directory": folder, "iso": iso, "suggested": suggested, "cli_explicit": explicit,
            "cli_suggested": sugg}


def label_map_case(args, work):
    """A .seg.nrrd of three touching structures (two boxes and a ball, the
    segments' names and colours in its header), a colour table, a label map
    with a fraction; the CLI's per-label JSON of each good case."""
    v = label_volumes.organs()
    n = v.shape[0]
    seg = os.path.join(work, "organs.seg.nrrd")
    label_volumes.write_seg_nrrd(seg, v, (0.8, 0.8, 1.5))
    table = os.path.join(work, "organs.ctbl")
    with open(table, "w") as fp:
        fp.write("# 3D Slicer colour table\n2 Right-Kidney 12 34 56 255\n")
    fractions = os.path.join(work, "fractions.nrrd")
    f = v.astype(np.float32)
    f[5, 5, 5] = 1.5
    with open(fractions, "wb") as fp:
        fp.write(("NRRD0004\ntype: float\ndimension: 3\nsizes: %d %d %d\nencoding: raw\n"
                  "endian: little\n\n" % (n, n, n)).encode() + f.astype("<f4").tobytes())

    def cli(extra, tag):
        out = os.path.join(work, "labels_%s" % tag) + "/"
        cmd = [args.cli, "extract", seg, "--labels", "all", "--pad", "-o", out, "--json",
               out.rstrip("/") + ".json", "--quiet"] + extra
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        if r.returncode != 0:
            sys.exit("isomend CLI failed (%s): %s" % (" ".join(cmd), r.stderr.strip()))
        with open(out.rstrip("/") + ".json") as fp:
            return {str(l["value"]): l for l in json.load(fp)["labels"]}

    return {"path": seg, "segments": label_volumes.SEGMENTS, "table": table, "fractions": fractions,
            "cli": cli([], "all")}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--blender", required=True)
    ap.add_argument("--package", "--zip", dest="package", required=True)
    ap.add_argument("--install", choices=("legacy", "extension"), default="legacy")
    ap.add_argument("--get-test-data")
    ap.add_argument("--cli", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--sample")
    ap.add_argument("--mode", choices=("background", "gui", "refuse"), default="background",
                    help="gui: the interactive, modal import under Xvfb (progress in a worker "
                         "thread, Esc cancels) with blender_modal_test.py; refuse: packages whose "
                         "libraries cannot load here refuse with a message (blender_refuse_test.py)")
    args = ap.parse_args()

    work = os.path.abspath(args.work)
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)

    cases = []
    # 1. folder of u8 slices, explicit spacing, fixed iso: many DMC mending quads
    folder = os.path.join(work, "foam_stack")
    os.makedirs(folder)
    g = foam()
    for k in range(g.shape[0]):
        tifffile.imwrite(os.path.join(folder, "slice_%d.tif" % k), g[k])
    base = {"use_suggested_iso": False, "iso": 127.5, "method": "DMC", "pad": True, "smooth": True}
    cases.append({"name": "foam_stack", "directory": folder, "files": [],
                  "params": dict(base, spacing=(1.0, 1.0, 1.0), unit_scale=0.01),
                  "cli_source": [folder]})
    cases.append({"name": "foam_stack", "directory": folder, "files": [],
                  "params": dict(base, spacing=(0.5, 0.75, 2.0), unit_scale=0.01),
                  "cli_source": [folder], "same_as": 0})
    # the same slices selected one by one (listed out of order: the add-on sorts them naturally)
    names = ["slice_%d.tif" % k for k in range(g.shape[0])]
    shuffled = sorted(names)  # slice_0, slice_1, slice_10, ...: not the stack order
    cases.append({"name": "slice", "directory": folder, "files": shuffled,
                  "params": dict(base, spacing=(1.0, 1.0, 1.0), unit_scale=0.01, method="MC",
                                 gradient_normals=False),
                  "cli_source": [os.path.join(folder, n) for n in names]})
    # methods added to the library after the thesis's three appear in the enum
    # the package's own wrapper and libraries, unpacked
    unpacked = os.path.join(work, "package")
    with zipfile.ZipFile(args.package) as zf:
        zf.extractall(unpacked)
    inner = os.path.join(unpacked, "isomend_import") if args.install == "legacy" else unpacked
    for name in os.listdir(os.path.join(inner, "lib")):
        os.chmod(os.path.join(inner, "lib", name), 0o755)
    sys.path.insert(0, inner)
    os.environ.pop("ISOMEND_LIB_DIR", None)
    import isomend  # the package's wrapper
    extra = [m for m in isomend.available_methods() if m not in ("dmc", "mc", "durst")]
    if extra:
        pick = "mc33" if "mc33" in extra else extra[0]
        cases.append({"name": "foam_stack", "directory": folder, "files": [],
                      "params": dict(base, spacing=(1.0, 1.0, 1.0), unit_scale=0.01, method=pick.upper()),
                      "cli_source": [folder]})
    # 2. float32 multi-page TIFF, suggested iso, Durst
    multi = os.path.join(work, "peanut.tif")
    tifffile.imwrite(multi, blob())
    cases.append({"name": "peanut", "directory": work, "files": ["peanut.tif"],
                  "params": {"use_suggested_iso": True, "iso": 0.0, "method": "DURST", "pad": True,
                             "smooth": False, "spacing": (0.0, 0.0, 0.0), "unit_scale": 0.001},
                  "cli_source": [multi]})
    # 3. the real MRI sample (NRRD), suggested iso, DMC
    if args.sample and os.path.exists(args.sample):
        cases.append({"name": "anatomical", "directory": os.path.dirname(os.path.abspath(args.sample)),
                      "files": [os.path.basename(args.sample)],
                      "params": {"use_suggested_iso": True, "iso": 0.0, "method": "DMC", "pad": True,
                                 "smooth": True, "spacing": (0.0, 0.0, 0.0), "unit_scale": 0.001},
                      "cli_source": [os.path.abspath(args.sample)]})
    if args.mode == "refuse":
        sys.exit(refuse(args, work, folder, inner))
    # 4. DICOM (written by tests/io/gen_dicom.py with pydicom): a CT folder at
    # the bone level by default, turned into patient space (oblique), and the
    # second series of a folder holding two
    dicom = os.path.join(work, "dicom")
    if args.mode == "background":
        subprocess.run([sys.executable, os.path.join(HERE, "..", "io", "gen_dicom.py"), dicom,
                        os.path.join(HERE, "..", "..", "samples")], check=True, stdout=subprocess.DEVNULL)
        dparams = {"use_suggested_iso": True, "iso": 0.0, "method": "DMC", "pad": True, "smooth": True,
                   "spacing": (0.0, 0.0, 0.0), "unit_scale": 0.001}
        for name, extra in (("ct_oblique", {}), ("ct", {}), ("ct_feet_first", {}),
                            ("ct_oblique", {"grid_axes": True}), ("two_series", {"series": "2"})):
            cases.append({"name": name, "directory": os.path.join(dicom, name), "files": [],
                          "params": dict(dparams, **extra), "cli_source": [os.path.join(dicom, name)]})
        # issue 34: a series whose slice spacing changes part-way (2.5 mm, then 5
        # mm gaps), once refused: at the bone level (closed, the CLI's mesh), and
        # at iso -1000.5 unpadded, where the air's noise crosses every slice, so
        # that the vertices show where each slice is (cases.json's slice origins)
        with open(os.path.join(dicom, "cases.json")) as fp:
            uneven = json.load(fp)["two_spacings"]
        A = np.array(uneven["affine"], float)
        slice_z = (np.array(uneven["slice_origins"], float) @ A[:, :3].T + A[:, 3])[:, 2]
        assert uneven["warning"] and np.ptp(np.diff(slice_z)) > 1.0, "two_spacings must be uneven"
        source = os.path.join(dicom, "two_spacings")
        cases.append({"name": "two_spacings", "directory": source, "files": [], "params": dict(dparams),
                      "cli_source": [source], "slice_z": slice_z.tolist()})
        cases.append({"name": "two_spacings", "directory": source, "files": [],
                      "params": dict(dparams, use_suggested_iso=False, iso=-1000.5, pad=False,
                                     smooth=False, unit_scale=1.0),
                      "cli_source": [source], "slice_z": slice_z.tolist(), "every_slice": True})
    if args.mode == "gui":
        cases = cases[:1]  # the modal test imports the first case only
    for i, case in enumerate(cases):
        case["cli"] = run_cli(args.cli, work, "case%d" % i, case["cli_source"], case["params"])
        case["cli_bbox"] = case["cli"]["bbox"]
    for i, case in enumerate(cases):
        c = case["cli"]
        print("case %d %-13s %s: CLI %d vertices, %d triangles, %d mending, iso %g"
              % (i, case["name"], case["params"]["method"], c["vertices"], c["triangles"],
                 c["triangles_by_origin"]["mend"], c["iso"]))
    assert cases[0]["cli"]["triangles_by_origin"]["mend"] > 0, "the foam case must exercise mending"
    for case in cases:
        if "slice_z" in case:
            geo = case["cli"]["geometry"]
            assert not geo["uniform"] and geo["warning"], "the CLI must find %s uneven: %s" % (case["name"], geo)

    # broken inputs: each must raise RuntimeError naming the reason
    mismatch = os.path.join(work, "mismatch")
    os.makedirs(mismatch)
    for k in range(3):
        tifffile.imwrite(os.path.join(mismatch, "m_%d.tif" % k), np.zeros((8, 9 if k == 2 else 8), np.uint8))
    empty = os.path.join(work, "empty")
    os.makedirs(empty)
    with open(os.path.join(empty, "notes.txt"), "w") as fp:
        fp.write("no images here\n")
    errors = [
        {"directory": os.path.join(work, "does_not_exist"), "files": [], "expect": "folder not found"},
        {"directory": mismatch, "files": [], "expect": "m_2.tif"},
        {"directory": empty, "files": [], "expect": "no image files"},
        {"directory": work, "files": ["peanut.tif"], "spacing": (1.0, 0.0, 1.0), "expect": "spacing"},
    ]
    if args.mode == "background":
        errors += [
            {"directory": os.path.join(dicom, "two_series"), "files": [], "expect": "2 DICOM series|T1"},
            {"directory": os.path.join(dicom, "two_series"), "files": [], "series": "3",
             "expect": "no series 3"},
            {"directory": os.path.join(dicom, "duplicate"), "files": [], "expect": "at the same position"},
        ]

    big = None
    if args.mode == "gui":
        # a stack large enough that Esc arrives while it is still being read (128
        # headers, 9 MB), whose surface is small (a blob) so that an import Esc
        # arrives too late for is built quickly
        big = os.path.join(work, "big_stack")
        os.makedirs(big)
        z, y, x = np.mgrid[0:128, 0:192, 0:192].astype(np.float32)
        r2 = (x - 96.3) ** 2 + (y - 95.7) ** 2 + (z - 64.2) ** 2
        v = (4000 * np.exp(-r2 / 2500)).astype(np.uint16)
        for k in range(v.shape[0]):
            tifffile.imwrite(os.path.join(big, "b_%03d.tif" % k), v[k])

    # issue 37: the operator's post-processing (Minimum Component, Smooth
    # Iterations, Decimate Ratio) on the foam stack equals the CLI's
    # --min-component 20 --smooth 5 --decimate 0.2 (the same core calls)
    post = None
    if args.mode == "background":
        out_json = os.path.join(work, "post.cli.json")
        cmd = [args.cli, "extract", folder, "-o", os.path.join(work, "post.cli.ply"), "--iso", "127.5",
               "--pad", "--spacing", "1,1,1", "--min-component", "20", "--smooth", "5",
               "--decimate", "0.2", "--json", out_json, "--quiet"]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        if r.returncode != 0:
            sys.exit("isomend CLI failed (%s): %s" % (" ".join(cmd), r.stderr.strip()))
        with open(out_json) as fp:
            cli_post = json.load(fp)
        assert cli_post["postprocess"]["clean"]["components_after"] < \
            cli_post["postprocess"]["clean"]["components_before"], "the foam must have specks"
        post = {"directory": folder, "params": {"iso": 127.5, "pad": True, "spacing": (1.0, 1.0, 1.0),
                                                "unit_scale": 0.01, "min_component": 20,
                                                "smooth_iterations": 5, "decimate": 0.2},
                "cli": cli_post, "plain_triangles": cases[0]["cli"]["triangles"]}

    # issue 36: a label map, one object per label (the CLI's per-label counts)
    labels = None
    if args.mode == "background":
        labels = label_map_case(args, work)

    explicit = None
    if args.get_test_data and args.mode == "background":
        explicit = real_stack_case(args, work)

    spec = os.path.join(work, "cases.json")
    with open(spec, "w") as fp:
        json.dump({"package": os.path.abspath(args.package), "install": args.install, "cases": cases,
                   "errors": errors, "big": big, "explicit_iso": explicit, "postprocess": post,
                   "labels": labels},
                  fp, indent=1)

    env = blender_env(work, "")
    if args.mode == "background":
        cmd = [args.blender, "-b", "--factory-startup", "-noaudio", "--python-exit-code", "1",
               "--python", os.path.join(HERE, "blender_import_test.py"), "--", spec]
    else:
        xvfb = shutil.which("xvfb-run")
        if not xvfb:
            sys.exit("xvfb-run not found (apt-get install xvfb xauth)")
        cmd = [xvfb, "-a", "-s", "-screen 0 1024x768x24", args.blender, "--factory-startup", "-noaudio",
               "--enable-event-simulate", "--python", os.path.join(HERE, "blender_modal_test.py"),
               "--", spec]
    r = subprocess.run(cmd, env=env, timeout=300, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       text=True)
    print(r.stdout, flush=True)
    if r.returncode != 0:
        sys.exit("Blender test failed (exit %d)" % r.returncode)
    # an exception inside the add-on (an update callback, a draw function) is
    # printed by Blender and swallowed: any traceback fails the test
    if "Traceback (most recent call last)" in r.stdout:
        sys.exit("Blender printed a Python traceback (above)")
    # the operator's WARNING report (Blender prints reports in background mode):
    # the importer's geometry warning, the one the CLI gives, for each uneven series
    if args.mode == "background":
        for case in cases:
            warning = case["cli"].get("geometry", {}).get("warning")
            if warning and "Warning: %s: %s" % (case["name"], warning) not in r.stdout:
                sys.exit("Blender did not report the warning %r for %s" % (warning, case["name"]))


if __name__ == "__main__":
    main()
