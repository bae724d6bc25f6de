#!/usr/bin/env bash
# The install rules: `cmake --install` puts the header, the libraries, the
# pkg-config file and the command line in a prefix, and a program built with
# `pkg-config --cflags --libs isomend` (the README's example) links and runs.
# Usage: install_test.sh BUILD_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
build="$1" src="$2" work="$3"
rm -rf "$work" && mkdir -p "$work"
prefix="$work/prefix"
cmake --install "$build" --prefix "$prefix" --component Unspecified >/dev/null
libdir=$(dirname "$(find "$prefix" -name isomend.pc | head -n1)")/..
test -f "$prefix/include/isomend.h" || { echo "missing include/isomend.h"; exit 1; }
ls "$libdir"/libisomend.so* "$libdir"/libisomend.a >/dev/null
export PKG_CONFIG_PATH="$libdir/pkgconfig"
# shellcheck disable=SC2046
cc -std=c11 "$src/examples/sphere.c" $(pkg-config --cflags --libs isomend) -lm -o "$work/sphere"
LD_LIBRARY_PATH="$libdir" "$work/sphere"
cc -std=c11 "$src/examples/sphere.c" $(pkg-config --cflags isomend) \
   "$libdir/libisomend.a" -lpthread -lm -o "$work/sphere_static"
"$work/sphere_static" >/dev/null
if [ -x "$prefix/bin/isomend" ]; then
  LD_LIBRARY_PATH="$libdir" "$prefix/bin/isomend" --version
fi
echo "install ok: $prefix"
