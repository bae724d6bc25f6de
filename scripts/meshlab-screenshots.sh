#!/usr/bin/env bash
# Recreates the README's MeshLab screenshots (docs/img/meshlab-*.png): the
# MeshLab GUI of a private prefix (scripts/meshlab-prefix.sh) runs under Xvfb,
# xdotool opens Filters > Create New Mesh Layer > Isosurface from Slice Stack
# (isomend), fills the source and iso level, applies, and ImageMagick's
# `import` captures the screen.  Coordinates assume the 1280x900 screen set
# here and MeshLab 2020.09's default layout.
#
# Usage: scripts/meshlab-screenshots.sh PREFIX SOURCE ISO [OUT_DIR]
#   e.g. scripts/meshlab-screenshots.sh build/meshlab-prefix \
#          ~/.cache/isomend/mri_t1_small/tiff 46.5 docs/img
# Needs: xvfb, xdotool, imagemagick (apt-get install xvfb xdotool imagemagick).
set -euo pipefail
die() { echo "meshlab-screenshots: $*" >&2; exit 1; }
[ $# -ge 3 ] || die "usage: $0 PREFIX SOURCE ISO [OUT_DIR]"
prefix="$1" source="$2" iso="$3" out="${4:-docs/img}"
for tool in Xvfb xdotool import convert; do
  command -v "$tool" >/dev/null || die "'$tool' not found (apt-get install xvfb xdotool imagemagick)"
done
[ -x "$prefix/bin/meshlab" ] || die "$prefix/bin/meshlab not found (build the isomend_meshlab_prefix target)"
mkdir -p "$out"
tmp="$(mktemp -d)"

display=""
for n in $(seq 90 120); do
  if [ ! -e "/tmp/.X$n-lock" ] && [ ! -e "/tmp/.X11-unix/X$n" ]; then display=":$n"; break; fi
done
[ -n "$display" ] || die "no free X display in :90..:120"
Xvfb "$display" -screen 0 1280x900x24 -nolisten tcp >"$tmp/xvfb.log" 2>&1 &
xvfb_pid=$!
gui_pid=""
cleanup() {
  [ -n "$gui_pid" ] && kill "$gui_pid" 2>/dev/null || true
  kill "$xvfb_pid" 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT
export DISPLAY="$display"
sleep 2

"$prefix/bin/meshlab" >"$tmp/meshlab.log" 2>&1 &
gui_pid=$!
win=""
for _ in $(seq 1 30); do
  win="$(xdotool search --onlyvisible --name '^MeshLab ' 2>/dev/null | head -n 1 || true)"
  [ -n "$win" ] && break
  sleep 1
done
[ -n "$win" ] || die "the MeshLab window did not appear (see $tmp/meshlab.log)"
xdotool windowsize "$win" 1280 900
sleep 1

# Filters > Create New Mesh Layer
xdotool mousemove 120 10 click 1; sleep 1
xdotool mousemove 200 136 click 1; sleep 1
import -window root "$tmp/menu.png"
convert "$tmp/menu.png" -crop 830x580+0+0 +repage "$out/meshlab-menu.png"

# > Isosurface from Slice Stack (isomend): the dialog
xdotool mousemove 600 361 click 1; sleep 2
xdotool mousemove 287 313 click 1; sleep 0.3
xdotool key ctrl+a; xdotool type --delay 5 "$source"
xdotool mousemove 287 344 click 1; sleep 0.3
xdotool key ctrl+a; xdotool type --delay 5 "$iso"
sleep 0.5
import -window root "$tmp/dialog.png"
convert "$tmp/dialog.png" -crop 458x693+0+0 +repage "$out/meshlab-dialog.png"

# Apply, close the dialog, turn the view a little
xdotool mousemove 339 669 click 1; sleep 5
xdotool mousemove 117 669 click 1; sleep 1
xdotool mousemove 430 500 mousedown 1
for _ in $(seq 1 20); do xdotool mousemove_relative -- 0 -8; sleep 0.03; done
for _ in $(seq 1 10); do xdotool mousemove_relative -- 8 0; sleep 0.03; done
xdotool mouseup 1; sleep 1
import -window root "$out/meshlab-result.png"
echo "meshlab-screenshots: wrote $out/meshlab-menu.png meshlab-dialog.png meshlab-result.png" >&2
