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
README).  Menu coordinates assume MeshLab 2022.02's layout in a 1280x1024
screen; the filter dialog's fields are found in a capture of the dialog (its
height follows the plugin's description and parameters), its buttons at its
bottom edge.  Every step waits for what it needs (a window, the fields drawn,
a line in MeshLab's log) instead of sleeping, and a failed step names itself
and leaves a capture fail-<step>.png in --work.

Usage: ISOMEND_XVFB_SCREEN=1280x1024x24 with_xvfb.py test_gui_2022.py --meshlab MESHLAB --plugin LIB.so --cli ISOMEND
           --work DIR [--source SRC --iso LEVEL] [--screenshots DIR]
Without --source, a torus stack is generated (40^3 u8, iso 127.5).
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_meshlab import FILTER, check, failures, read_ply, sphere_and_torus, write_tiff_folder  # noqa: E402

SCREEN = (1280, 1024)
# Filters menu, its "Create New Mesh Layer" submenu, the filter's entry
# (alphabetical among MeshLab 2022.02's creation filters, after "Implicit Surface")
MENU_FILTERS = (116, 9)
MENU_CREATE = (194, 125)
MENU_ENTRY = (572, 332)
# File > Export Mesh... (when ctrl+E does not reach the main window)
MENU_FILE, MENU_EXPORT = (35, 9), (92, 171)
# the filter dialog's Close and Apply buttons: the bottom row, left and right
# half, 22 px above the dialog's lower edge
BUTTON_FROM_BOTTOM = 22
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


def wait_gone(name, seconds=15):
    end = time.time() + seconds
    while time.time() < end and windows(name):
        time.sleep(0.3)
    return not windows(name)


def geometry(win, size=False):
    g = {}
    for line in xdo("getwindowgeometry", "--shell", win).splitlines():
        k, _, v = line.partition("=")
        g[k] = int(v) if v.lstrip("-").isdigit() else v
    return (g["X"], g["Y"], g["WIDTH"], g["HEIGHT"]) if size else (g["X"], g["Y"])


def click(x, y, pause=0.5):
    xdo("mousemove", x, y, "click", 1)
    time.sleep(pause)


def click_in(win, rel, pause=0.5):
    x, y = geometry(win)
    click(x + rel[0], y + rel[1], pause)


def screenshot(path, crop=None):
    subprocess.run(["import", "-window", "root", path], check=True)
    if crop:
        subprocess.run(["convert", path, "-crop", crop, "+repage", path], check=True)


def capture(win):
    """The window's pixels as it is drawn now (rows x columns x RGB)."""
    x, y, w, h = geometry(win, size=True)
    r = subprocess.run("import -window root -crop %dx%d+%d+%d +repage -depth 8 rgb:-" % (w, h, x, y),
                       shell=True, stdout=subprocess.PIPE, check=True)
    return np.frombuffer(r.stdout, np.uint8)[:w * h * 3].reshape(h, w, 3)


def dialog_fields(dlg, seconds=30):
    """The filter dialog's text fields, top to bottom (Source, Iso level, ...),
    as points relative to the dialog: the white runs at least 12 px tall down
    a column through the fields, taken once two captures agree (the dialog is
    laid out and drawn).  None when they do not show up."""
    end, last = time.time() + seconds, None
    while time.time() < end:
        img = capture(dlg)
        cx = img.shape[1] * 3 // 5
        white = (img[:, cx] >= 250).all(1)
        rows, start = [], None
        for y, wv in enumerate(list(white) + [False]):
            if wv and start is None:
                start = y
            elif not wv and start is not None:
                if y - start >= 12:
                    rows.append((cx, (start + y) // 2))
                start = None
        if len(rows) >= 2 and rows == last:
            return rows
        last = rows
        time.sleep(0.5)
    return None


def type_into(win, rel, text, seconds=15):
    """Clicks the field, replaces its text and waits until the field's pixels
    change (its text is drawn).  False when they never do."""
    x, y = rel
    before = capture(win)[y - 6:y + 6, x - 120:x + 120].copy()
    click_in(win, rel, 0.3)
    xdo("key", "ctrl+a")
    xdo("type", "--delay", 5, text)
    end = time.time() + seconds
    while time.time() < end:
        if not np.array_equal(capture(win)[y - 6:y + 6, x - 120:x + 120], before):
            return True
        time.sleep(0.3)
    return False


class Log:
    """MeshLab's output (stdout and stderr) as the test reads it: wait for a
    pattern in what was written after a mark."""

    def __init__(self, path):
        self.path = path

    def text(self):
        with open(self.path, errors="replace") as f:
            return f.read()

    def mark(self):
        return len(self.text())

    def wait(self, pattern, since=0, seconds=60, gui=None):
        end = time.time() + seconds
        while True:
            m = re.search(pattern, self.text()[since:], re.M)
            if m or time.time() > end or (gui is not None and gui.poll() is not None):
                return m
            time.sleep(0.3)


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
    mlog = Log(log.name)
    try:
        main_win = wait_window("^MeshLab %s" % version.replace(".", "\\."), 60)
        if not check(main_win is not None, "the MeshLab window appears"):
            return 1
        time.sleep(2)
        check(not windows("Error while loading plugins"),
              "no \"Error while loading plugins.\" box (every plugin loads, ours included)")
        xdo("windowsize", main_win, *SCREEN)
        time.sleep(1)

        def failed(step):
            path = os.path.join(a.work, "fail-%s.png" % step)
            screenshot(path)
            print("       (the screen then: %s)" % path)
        dlg_title = "^" + FILTER.replace("(", "\\(").replace(")", "\\)") + "$"

        def open_dialog(menu_shot=None):
            """Filters > Create New Mesh Layer > the entry; tried three times
            (a click into a menu still opening can miss).  The dialog's window
            or None."""
            for attempt in range(3):
                click(*MENU_FILTERS, pause=1)
                click(*MENU_CREATE, pause=1)
                xdo("mousemove", *MENU_ENTRY)
                time.sleep(0.5)
                if menu_shot and attempt == 0:
                    menu_shot()
                click(*MENU_ENTRY, pause=1)
                dlg = wait_window(dlg_title, 20)
                if dlg is not None:
                    return dlg
                print("  ...  no dialog after attempt %d, the menus closed, again" % (attempt + 1))
                for _ in range(3):
                    xdo("key", "Escape")
                    time.sleep(0.3)
            return None

        # 2. the menu and the dialog
        dlg = open_dialog(lambda: screenshot(os.path.join(shots, "meshlab-menu.png"),
                                             "780x540+0+0" if a.screenshots else None))
        if not check(dlg is not None, "Filters > Create New Mesh Layer > \"%s\" opens its dialog"
                     % FILTER):
            failed("dialog")
            return 1
        fields = dialog_fields(dlg)
        if not check(fields is not None, "the dialog shows its fields (Source, Iso level, ...)"):
            failed("fields")
            return 1
        _, _, dw, dh = geometry(dlg, size=True)
        apply_btn, close_btn = (dw * 3 // 4, dh - BUTTON_FROM_BOTTOM), (dw // 4, dh - BUTTON_FROM_BOTTOM)

        # 3. apply, export, compare
        typed = type_into(dlg, fields[0], source) and type_into(dlg, fields[1], "%r" % a.iso)
        if not check(typed, "Source and Iso level typed into the dialog's first two fields"):
            failed("typing")
            return 1
        x, y = geometry(dlg)
        screenshot(os.path.join(shots, "meshlab-dialog.png"),
                   "%dx%d+%d+%d" % (dw, dh, x, y) if a.screenshots else None)
        since = mlog.mark()
        click_in(dlg, apply_btn, pause=0.5)
        done = r"^LOG: \d Applied filter %s|isomend: error: .*" % re.escape(FILTER)
        m = mlog.wait(done, since, 30, gui)
        if m is None and not mlog.text()[since:].strip() and gui.poll() is None:
            # nothing at all in the log: the click did not reach the button
            print("  ...  nothing in MeshLab's log 30 s after Apply: Apply clicked again")
            click_in(dlg, apply_btn, pause=0.5)
            m = mlog.wait(done, since, 120, gui)
        applied = mlog.text()[since:]
        if not check(m is not None and m.group(0).startswith("LOG"),
                     "Apply: MeshLab applied the filter (%s)"
                     % (m.group(0) if m else "no \"Applied filter\" in its log")):
            failed("apply")
            return 1
        src = re.search(r"^LOG: \d isomend \S+: (.*) \(", applied, re.M)
        iso = re.search(r"^LOG: \d method .*, iso ([-+0-9.eE]+)", applied, re.M)
        layer = re.search(r"^LOG: \d layer \"(.*)\": \d+ vertices", applied, re.M)
        if not check(src is not None and src.group(1) == source and iso is not None
                     and abs(float(iso.group(1)) - a.iso) <= 1e-5 * max(1.0, abs(a.iso))
                     and layer is not None,
                     "the filter read the typed source at the typed iso level and made a layer "
                     "(log: source %s, iso %s, layer %s)"
                     % (src and src.group(1), iso and iso.group(1), layer and layer.group(1))):
            failed("applied-values")
            return 1
        click_in(dlg, close_btn, pause=0.5)
        check(wait_gone(dlg_title), "Close closes the dialog")
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
        save_title = "^Save \".*\" Layer$"
        save = wait_window(save_title, 10)
        how = "ctrl+E"
        if save is None:
            # the shortcut went elsewhere: the menu entry it stands for
            click(*MENU_FILE, pause=1)
            click(*MENU_EXPORT, pause=1)
            save, how = wait_window(save_title, 20), "File > Export Mesh..., ctrl+E did not"
        if not check(save is not None, "File > Export Mesh opens the save dialog (%s)" % how):
            failed("export")
            return 1
        name = xdo("getwindowname", save).strip()[len("Save \""):-len("\" Layer")]
        check(name == layer.group(1), "the save dialog is for the new layer \"%s\"" % name)
        click_in(save, SAVE_NAME, 0.3)
        xdo("windowfocus", "--sync", save)
        xdo("key", "ctrl+a")
        xdo("type", "--delay", 5, out_ply)
        xdo("key", "Return")
        opts = wait_window("^Choose Saving Options", 20)
        if not check(opts is not None, "MeshLab asks for the saving options"):
            failed("save-name")
            return 1
        time.sleep(0.5)
        since = mlog.mark()
        click_in(opts, OPT_VERT_NORMAL, 0.3)
        click_in(opts, OPT_OK, 0.5)
        saved = mlog.wait(r"^LOG: \d Saved Mesh %s " % re.escape(out_ply), since, 60, gui)
        if not check(saved is not None and os.path.exists(out_ply),
                     "MeshLab exported the layer \"%s\" to %s" % (name, out_ply)):
            failed("save")
        else:
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
        dlg = open_dialog()
        fields = dlg and dialog_fields(dlg)
        if not check(dlg is not None and fields is not None, "the dialog opens again"):
            failed("dialog-again")
        else:
            missing = os.path.join(a.work, "no_such_stack")
            if not check(type_into(dlg, fields[0], missing), "the missing source typed in"):
                failed("typing-missing")
            since = mlog.mark()
            click_in(dlg, apply_btn, pause=0.5)
            box = wait_window("^Filter Failure$", 60)
            if not check(box is not None, "MeshLab shows its \"Filter Failure\" box"):
                failed("failure-box")
            time.sleep(0.5)
            screenshot(os.path.join(a.work, "meshlab-failure.png"))
            reason = "isomend: error: source: %s: no such file or folder" % missing
            check(mlog.wait(re.escape(reason), since, 10) is not None,
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
