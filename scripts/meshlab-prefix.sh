#!/usr/bin/env bash
# Builds a private MeshLab prefix that loads extra plugins, without root and
# without writing anything under /usr.
#
# Usage: scripts/meshlab-prefix.sh PREFIX [PLUGIN.so ...]
#   PREFIX      folder to create or refresh (e.g. build/meshlab-prefix)
#   PLUGIN.so   plugins to add (symlinked, so a rebuild is picked up)
# Then:  PREFIX/bin/meshlab                         (the GUI)
#        xvfb-run -a PREFIX/bin/meshlabserver -l log.txt -s script.mlx -o out.ply -m vn
#
# Why copies: MeshLab 2020.09 loads plugins only from
# applicationDirPath()/../lib/x86_64-linux-gnu/meshlab/plugins, and
# applicationDirPath() follows /proc/self/exe, so a symlinked binary would
# still load /usr's plugin folder; a copied binary (RUNPATH
# $ORIGIN/../lib/x86_64-linux-gnu/meshlab) loads the prefix's.  The prefix
# holds:
#   bin/meshlab, bin/meshlabserver                    copies (2.3 MB)
#   lib/x86_64-linux-gnu/meshlab/libmeshlab-common.so symlink to the system's
#   lib/x86_64-linux-gnu/meshlab/plugins/*.so         symlinks to the stock
#                                                     plugins + PLUGIN.so
# Idempotent; the copies are refreshed when the system's binaries change.
# MESHLAB_BINDIR / MESHLAB_LIBDIR override where the installed MeshLab is
# (defaults /usr/bin and /usr/lib/x86_64-linux-gnu/meshlab).
set -euo pipefail

die() { echo "meshlab-prefix: $*" >&2; exit 1; }

[ $# -ge 1 ] || die "usage: $0 PREFIX [PLUGIN.so ...]"
prefix="$1"; shift
bindir="${MESHLAB_BINDIR:-/usr/bin}"
libdir="${MESHLAB_LIBDIR:-/usr/lib/x86_64-linux-gnu/meshlab}"

for exe in meshlab meshlabserver; do
  [ -x "$bindir/$exe" ] || die "$bindir/$exe not found (apt-get install meshlab)"
done
[ -f "$libdir/libmeshlab-common.so" ] || die "$libdir/libmeshlab-common.so not found"
[ -d "$libdir/plugins" ] || die "$libdir/plugins not found"
for p in "$@"; do
  [ -f "$p" ] || die "plugin $p not found"
done

mkdir -p "$prefix/bin" "$prefix/lib/x86_64-linux-gnu/meshlab/plugins"
prefix="$(cd "$prefix" && pwd)"
mldir="$prefix/lib/x86_64-linux-gnu/meshlab"

for exe in meshlab meshlabserver; do
  if ! cmp -s "$bindir/$exe" "$prefix/bin/$exe"; then
    cp -p "$bindir/$exe" "$prefix/bin/.$exe.tmp"
    mv -f "$prefix/bin/.$exe.tmp" "$prefix/bin/$exe"
  fi
done
ln -sfn "$libdir/libmeshlab-common.so" "$mldir/libmeshlab-common.so"

# Drop links whose target is gone (an uninstalled plugin, a moved build).
find "$mldir/plugins" -maxdepth 1 -type l ! -exec test -e {} \; -delete
for stock in "$libdir"/plugins/*.so; do
  ln -sfn "$stock" "$mldir/plugins/$(basename "$stock")"
done
for p in "$@"; do
  ln -sfn "$(cd "$(dirname "$p")" && pwd)/$(basename "$p")" "$mldir/plugins/$(basename "$p")"
done
echo "meshlab-prefix: $prefix ready ($(ls "$mldir/plugins" | wc -l) plugins)" >&2
