#!/bin/sh
# isomend_bench_extract --ab on a small volume: the build's shared library
# against itself must give byte-identical meshes (exit 0, "meshes identical")
# and a ratio per run; a file that is not the library must be refused with a
# message naming it (exit 1).
#   ab_smoke.sh PYTHON DRIVER LIBISOMEND.so WORKDIR
set -eu
python="$1" driver="$2" lib="$3" work="$4"
mkdir -p "$work"
vol="$work/sphere24.npy"
"$python" - "$vol" <<'PY'
import sys
import numpy as np
n = 24
z, y, x = np.mgrid[0:n, 0:n, 0:n].astype(np.float32)
f = 8.5 - np.sqrt((x - 11.3) ** 2 + (y - 12.1) ** 2 + (z - 11.7) ** 2)
np.save(sys.argv[1], f.astype(np.float32))
PY
out="$("$driver" "$vol" 0 --threads 2 --repeats 4 --ab "$lib" "$lib")"
echo "$out"
echo "$out" | grep -q "meshes identical" || { echo "ab_smoke: no 'meshes identical'" >&2; exit 1; }
echo "$out" | grep -q "^run 3: A .* ms, B .* ms, B / A " || { echo "ab_smoke: no per-run ratio" >&2; exit 1; }
set +e
err="$("$driver" "$vol" 0 --repeats 2 --ab "$lib" "$driver" 2>&1 >/dev/null)"
rc=$?
set -e
echo "$err"
[ "$rc" -eq 1 ] || { echo "ab_smoke: a non-library gave exit $rc, not 1" >&2; exit 1; }
echo "$err" | grep -q -- "--ab $driver" || { echo "ab_smoke: the message does not name the file" >&2; exit 1; }
echo "ab_smoke: ok"
