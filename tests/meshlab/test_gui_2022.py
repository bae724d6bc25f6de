#!/usr/bin/python3
"""The real MeshLab 2021.05+ GUI (Debian 13's 2022.02) with the plugin
installed the way a user installs it: copied into MeshLab's per-user
extra-plugins folder, ~/.local/share/VCG/MeshLab_64bit_fp/MeshLabExtraPlugins/
<version>/ (HOME is a fresh folder of the test).  Under Xvfb, xdotool drives
it as a user would:

  1. MeshLab starts without its "Error while loading plugins." box;
  2. Filters > Create New Mesh Layer lists the filter: the entry opens the
     filter's dialog (a window titled with the filter's name);
  3. Source and Iso level typed in, Apply: the layer is exported with
     File > Export Mesh (PLY, vertex normals ticked), and that file equals
     `isomend extract`'s mesh (counts, positions, triangles, normals);
  4. a missing source: MeshLab shows its "Filter Failure" box with the
     filter's reason, and is still running.
ImageMagick's `import` takes screenshots of the menu, the dialog, the result
and the failure (kept in --work, or cropped into --screenshots for the
README).  Coordinates assume MeshLab 2022.02's layout in a 1280x900 screen.

Usage: ISOMEND_XVFB_SCREEN=1280x900x24 with_xvfb.py test_gui_2022.py --meshlab MESHLAB --plugin LIB.so --cli ISOMEND
           --work DIR [--source SRC --iso LEVEL] [--screenshots DIR]
Without --source, a torus stack is generated (40^3 u8, iso 127.5).
"""
import argparse
import os
import shutil
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_meshlab import FILTER, check, failures, read_ply, sphere_and_torus, write_tiff_folder  # noqa: E402

SCREEN = (1280, 900)
# Filters menu, its "Create New Mesh Layer" submenu, the filter's entry
# (alphabetical among MeshLab 2022.02's creation filters, after "Implicit Surface")
MENU_FILTERS = (116, 9)
MENU_CREATE = (194, 125)
MENU_ENTRY = (572, 332)
# in the filter's dialog, relative to its window
DLG_SOURCE, DLG_ISO, DLG_APPLY, DLG_CLOSE = (286, 266), (286, 295), (330, 649), (114, 649)
# the export dialogs, relative to their windows
SAVE_NAME = (300, 358)
OPT_VERT_NORMAL, OPT_OK = (29, 131), (550, 337)


def xdo(*args, check_rc=True):
    r = subprocess.run(["xdotool"] + [str(a) for a in args], stdout=subprocess.PIPE,
                       stderr=subprocess.DEVNULL, universal_newlines=True)
    if check_rc and r.returncode != 0:
        raise RuntimeError("xdotool %s failed" % " ".join(map(str, args)))
    return r.stdout


def windows(name):
    """Visible windows whose title matches the regular expression."""
    out = xdo("search", "--onlyvisible", "--name", name, check_rc=False)
    return [w for w in out.split() if w.strip()]


def wait_window(name, seconds=30):
    end = time.time() + seconds
    while time.time() < end:
        found = windows(name)
        if found:
            return found[0]
        time.sleep(0.3)
    return None


def geometry(win):
    g = {}
    for line in xdo("getwindowgeometry", "--shell", win).splitlines():
        k, _, v = line.partition("=")
        g[k] = int(v) if v.lstrip("-").isdigit() else v
    return g["X"], g["Y"]


def click(x, y, pause=0.5):
    xdo("mousemove", x, y, "click", 1)
    time.sleep(pause)


def click_in(win, rel, pause=0.5):
    x, y = geometry(win)
    click(x + rel[0], y + rel[1], pause)


def type_into(win, rel, text):
    click_in(win, rel, 0.3)
    xdo("key", "ctrl+a")
    xdo("type", "--delay", 5, text)


def screenshot(path, crop=None):
    subprocess.run(["import", "-window", "root", path], check=True)
    if crop:
        subprocess.run(["convert", path, "-crop", crop, "+repage", path], check=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshlab", required=True)
    ap.add_argument("--plugin", required=True)
    ap.add_argument("--cli", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--source")
    ap.add_argument("--iso", type=float, default=127.5)
    ap.add_argument("--screenshots", help="write the README's cropped screenshots here")
    a = ap.parse_args()
    if not os.environ.get("DISPLAY"):
        print("no DISPLAY: run under with_xvfb.py")
        return 1
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    shots = a.screenshots or a.work
    os.makedirs(shots, exist_ok=True)

    version = subprocess.run([a.meshlab, "--version"], stdout=subprocess.PIPE,
                             universal_newlines=True).stdout.split()[-1]
    home = os.path.join(a.work, "home")
    extra = os.path.join(home, ".local/share/VCG/MeshLab_64bit_fp/MeshLabExtraPlugins", version)
    os.makedirs(extra)
    shutil.copy(a.plugin, extra)
    print("MeshLab %s, the plugin copied into %s" % (version, extra))
    source = a.source
    if not source:
        _, torus = sphere_and_torus()
        source = os.path.join(a.work, "torus")
        write_tiff_folder(source, torus)
    out_ply = os.path.join(a.work, "gui.ply")

    env = dict(os.environ, HOME=home)
    for k in ("XDG_DATA_HOME", "XDG_CONFIG_HOME", "XDG_CACHE_HOME"):
        env.pop(k, None)
    log = open(os.path.join(a.work, "meshlab.log"), "w")
    gui = subprocess.Popen([a.meshlab], env=env, stdout=log, stderr=subprocess.STDOUT)
    try:
        main_win = wait_window("^MeshLab %s" % version.replace(".", "\\."), 60)
        if not check(main_win is not None, "the MeshLab window appears"):
            return 1
        time.sleep(2)
        check(not windows("Error while loading plugins"),
              "no \"Error while loading plugins.\" box (every plugin loads, ours included)")
        xdo("windowsize", main_win, *SCREEN)
        time.sleep(1)

        # 2. the menu and the dialog
        click(*MENU_FILTERS, pause=1)
        click(*MENU_CREATE, pause=1)
        xdo("mousemove", *MENU_ENTRY)
        time.sleep(0.5)
        screenshot(os.path.join(shots, "meshlab-menu.png"), "780x540+0+0" if a.screenshots else None)
        click(*MENU_ENTRY, pause=1)
        dlg = wait_window("^" + FILTER.replace("(", "\\(").replace(")", "\\)") + "$", 10)
        if not check(dlg is not None, "Filters > Create New Mesh Layer > \"%s\" opens its dialog"
                     % FILTER):
            screenshot(os.path.join(a.work, "no-dialog.png"))
            return 1

        # 3. apply, export, compare
        type_into(dlg, DLG_SOURCE, source)
        type_into(dlg, DLG_ISO, "%r" % a.iso)
        time.sleep(0.5)
        x, y = geometry(dlg)
        screenshot(os.path.join(shots, "meshlab-dialog.png"),
                   "%dx%d+%d+%d" % (445, 671, x, y) if a.screenshots else None)
        click_in(dlg, DLG_APPLY, pause=1)
        t0 = time.time()
        while time.time() - t0 < 120 and "Applied filter " + FILTER not in open(log.name).read():
            time.sleep(0.5)
        time.sleep(1)
        click_in(dlg, DLG_CLOSE, pause=1)
        if a.screenshots:
            # turn the view a little, as a user would look at it
            xdo("mousemove", 440, 560, "mousedown", 1)
            for dx, dy in [(0, -8)] * 15 + [(8, 0)] * 8:
                xdo("mousemove_relative", "--", dx, dy)
                time.sleep(0.03)
            xdo("mouseup", 1)
            time.sleep(1)
        screenshot(os.path.join(shots, "meshlab-result.png"))

        xdo("mousemove", 640, 400)
        xdo("windowfocus", "--sync", main_win)
        xdo("key", "ctrl+e")
        save = wait_window("^Save \".*\" Layer$", 10)
        if not check(save is not None, "File > Export Mesh (ctrl+E) opens the save dialog"):
            return 1
        layer = xdo("getwindowname", save).strip()[len("Save \""):-len("\" Layer")]
        click_in(save, SAVE_NAME, 0.3)
        xdo("windowfocus", "--sync", save)
        xdo("type", "--delay", 5, out_ply)
        xdo("key", "Return")
        opts = wait_window("^Choose Saving Options", 10)
        if not check(opts is not None, "MeshLab asks for the saving options"):
            return 1
        click_in(opts, OPT_VERT_NORMAL, 0.3)
        click_in(opts, OPT_OK, 1)
        t0 = time.time()
        while time.time() - t0 < 30 and not os.path.exists(out_ply):
            time.sleep(0.3)
        time.sleep(1)
        if check(os.path.exists(out_ply), "MeshLab exported the layer \"%s\" to %s" % (layer, out_ply)):
            r = subprocess.run([a.cli, "extract", source, "--iso", repr(a.iso), "--pad", "-o",
                                os.path.join(a.work, "cli.ply"), "--quiet"])
            check(r.returncode == 0, "isomend extract on the same source")
            v, t = read_ply(out_ply)
            rv, rt = read_ply(os.path.join(a.work, "cli.ply"))
            check(len(v) == len(rv) and len(t) == len(rt),
                  "the GUI's vertex/triangle counts %d/%d equal the CLI's %d/%d"
                  % (len(v), len(t), len(rv), len(rt)))
            if len(v) == len(rv) and len(t) == len(rt):
                pos = np.stack([v["x"], v["y"], v["z"]], 1)
                rpos = np.stack([rv["x"], rv["y"], rv["z"]], 1)
                check(np.array_equal(pos, rpos) and np.array_equal(t, rt),
                      "positions and triangles identical to the CLI's")
                if "nx" in v.dtype.names:
                    n = np.stack([v["nx"], v["ny"], v["nz"]], 1).astype(np.float64)
                    rn = np.stack([rv["nx"], rv["ny"], rv["nz"]], 1).astype(np.float64)
                    check(np.abs(n - rn).max() < 1e-6, "normals equal the CLI's")
                else:
                    check(False, "the exported PLY has vertex normals")

        # 4. a missing source
        click(*MENU_FILTERS, pause=1)
        click(*MENU_CREATE, pause=1)
        click(*MENU_ENTRY, pause=1)
        dlg = wait_window("^" + FILTER.replace("(", "\\(").replace(")", "\\)") + "$", 10)
        if check(dlg is not None, "the dialog opens again"):
            missing = os.path.join(a.work, "no_such_stack")
            type_into(dlg, DLG_SOURCE, missing)
            click_in(dlg, DLG_APPLY, pause=2)
            box = wait_window("^Filter Failure$", 10)
            check(box is not None, "MeshLab shows its \"Filter Failure\" box")
            time.sleep(0.5)
            screenshot(os.path.join(a.work, "meshlab-failure.png"))
            text = open(log.name).read()
            check("isomend: error: source: %s: no such file or folder" % missing in text,
                  "MeshLab's log names the missing source")
            check(gui.poll() is None, "MeshLab is still running")
    finally:
        if gui.poll() is None:
            gui.terminate()
            try:
                gui.wait(timeout=10)
            except subprocess.TimeoutExpired:
                gui.kill()
        log.close()
    print("GUI test: %s" % ("FAILED: %d" % len(failures) if failures else "all ok"))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
