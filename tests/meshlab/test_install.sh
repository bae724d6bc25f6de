#!/usr/bin/env bash
# `cmake --install` of the plugin (component meshlab_plugin, into a DESTDIR):
# it lands in the installed MeshLab's plugin folder with a RUNPATH to the
# install libdir, and the *installed* file runs the filter (libisomend found
# through LD_LIBRARY_PATH, since the DESTDIR is not the real prefix):
#   MeshLab 2020.09: a MeshLab prefix holding it, through meshlabserver;
#   MeshLab 2021.05+ (HARNESS given): MeshLab's own PluginManager loads it
#   (meshlab_run_filter), with the stock measure and PLY plugins of STOCK_DIR.
# Usage: test_install.sh BUILD_DIR PLUGIN_DIR INSTALL_LIBDIR LIB_DIRS WORK [HARNESS STOCK_DIR]
#   (2020.09: with $DISPLAY set, e.g. under with_xvfb.py)
set -euo pipefail
build="$1" plugin_dir="$2" libdir="$3" lib_dirs="$4" work="$5" harness="${6:-}" stock="${7:-}"
src="$(cd "$(dirname "$0")/../.." && pwd)"
rm -rf "$work"; mkdir -p "$work"
fail() { echo "FAIL: $*"; exit 1; }

DESTDIR="$work/dest" cmake --install "$build" --component meshlab_plugin >"$work/install.log" 2>&1 \
  || { cat "$work/install.log"; fail "cmake --install failed"; }
installed="$work/dest$plugin_dir/libfilter_isomend.so"
[ -f "$installed" ] || { cat "$work/install.log"; fail "no $installed"; }
echo "ok   installed into $plugin_dir (under DESTDIR)"
files=$(find "$work/dest" -type f | wc -l)
[ "$files" = 1 ] || fail "the meshlab_plugin component installs $files files, expected 1"
runpath=$(readelf -d "$installed" | sed -n 's/.*RUNPATH.*\[\(.*\)\]/\1/p')
[ "$runpath" = "$libdir" ] || fail "RUNPATH '$runpath', expected '$libdir'"
echo "ok   RUNPATH $runpath"

/usr/bin/python3 - "$work" <<'PY'
import sys, os, numpy as np, tifffile
work = sys.argv[1]
os.makedirs(work + "/stack")
z, y, x = np.mgrid[0:12, 0:12, 0:12]
v = (255 * (((x - 5.5) ** 2 + (y - 5.5) ** 2 + (z - 5.5) ** 2) < 16)).astype(np.uint8)
for k in range(12):
    tifffile.imwrite("%s/stack/s_%02d.tif" % (work, k), v[k])
PY
if [ -z "$harness" ]; then
  bash "$src/scripts/meshlab-prefix.sh" "$work/prefix" "$installed" 2>/dev/null
  sed -e "s#@SOURCE@#$work/stack#" "$src/tests/meshlab/sample.mlx" >"$work/run.mlx"
  LD_LIBRARY_PATH="$lib_dirs" "$work/prefix/bin/meshlabserver" -l "$work/log.txt" -s "$work/run.mlx" \
    -o "$work/out.ply" -m vn >"$work/stdout.txt" 2>&1 || { cat "$work/log.txt"; fail "meshlabserver failed"; }
else
  LD_LIBRARY_PATH="$lib_dirs" "$harness" --plugin "$installed" --plugin "$stock/libfilter_measure.so" \
    --plugin "$stock/libio_base.so" --log "$work/log.txt" \
    --filter "Isosurface from Slice Stack (isomend)" --set "source=$work/stack" --set iso=127.5 \
    --filter "Compute Topological Measures" --save "$work/out.ply" >"$work/stdout.txt" 2>&1 \
    || { cat "$work/stdout.txt"; fail "meshlab_run_filter failed"; }
  grep -q "\"plugin\": \"$installed\", \"loaded\": true" "$work/stdout.txt" \
    || { cat "$work/stdout.txt"; fail "MeshLab's loader did not accept the installed file"; }
  echo "ok   MeshLab's PluginManager loads the installed file"
fi
grep -q "Boundary Edges 0" "$work/log.txt" || { cat "$work/log.txt"; fail "no closed surface"; }
grep -q "^element face [1-9]" "$work/out.ply" || fail "empty PLY"
echo "ok   the installed plugin runs: $(grep -m1 'vertices' "$work/log.txt")"
