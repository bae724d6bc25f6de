#!/usr/bin/env bash
# Instruction profile of isomend_extract() on the benchmark's cached volumes:
# exact counts (callgrind), not disturbed by other jobs on a shared machine.
#
#   bench/profile_core.sh BUILD_DIR [VOLUME.npy ...]   (default: the 256^3 sphere and noise)
#   env: THREADS (1), EXTRA (more isomend_bench_extract options, e.g. --no-normals)
#
# Prints, per volume: instructions in total, per voxel, per triangle, and the
# functions of the core above 1 %.  Run `bench/bench.py --quick` once first so
# that the volumes exist in ~/.cache/isomend-bench.
set -euo pipefail
build="${1:?usage: bench/profile_core.sh BUILD_DIR [VOLUME.npy ...]}"
shift
driver="$build/bench/isomend_bench_extract"
[ -x "$driver" ] || { echo "profile_core.sh: $driver not built (cmake --build $build --target isomend_bench_extract)" >&2; exit 1; }
command -v valgrind >/dev/null || { echo "profile_core.sh: valgrind not installed" >&2; exit 1; }
cache="${XDG_CACHE_HOME:-$HOME/.cache}/isomend-bench"
vols=("$@")
[ ${#vols[@]} -gt 0 ] || vols=("$cache/v1-sphere-256-f32.npy" "$cache/v1-noise-256-f32.npy")
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
for v in "${vols[@]}"; do
  [ -f "$v" ] || { echo "profile_core.sh: $v: no such volume (run bench/bench.py --quick first)" >&2; exit 1; }
  iso=0
  case "$v" in *-u8.npy) iso=127.5 ;; *colin27*) iso=60 ;; esac
  # shellcheck disable=SC2086
  valgrind --tool=callgrind --toggle-collect=isomend_extract --callgrind-out-file="$tmp/cg" \
    "$driver" "$v" "$iso" --threads "${THREADS:-1}" --repeats 1 ${EXTRA:-} >"$tmp/out" 2>"$tmp/err" ||
    { cat "$tmp/err" >&2; exit 1; }
  /usr/bin/python3 - "$v" "$tmp/cg" "$tmp/out" <<'EOF'
import re, subprocess, sys
vol, cg, out = sys.argv[1:]
text = open(out).read()
m = re.search(r"(\d+) triangles, (\d+) vertices", text)
tris, verts = int(m.group(1)), int(m.group(2))
dims = re.search(r"\((\d+) x (\d+) x (\d+)", text)
voxels = int(dims.group(1)) * int(dims.group(2)) * int(dims.group(3))
ann = subprocess.run(["callgrind_annotate", "--inclusive=no", cg], capture_output=True,
                     text=True).stdout
rows = re.findall(r"^\s*([\d,]+) \(\s*([\d.]+)%\)\s+(\S+)", ann, re.M)
total = int(rows[0][0].replace(",", ""))
print("%s: %d triangles, %d vertices; %.0f M instructions = %.1f per voxel, %.0f per triangle"
      % (vol.rsplit("/", 1)[-1], tris, verts, total / 1e6, total / voxels, total / max(tris, 1)))
for ir, pct, fn in rows[1:]:
    if float(pct) < 1.0:
        break
    print("  %6.1f %%  %8.0f M  %s" % (float(pct), int(ir.replace(",", "")) / 1e6,
                                       fn.split(":")[-1] if ":" in fn else fn))
EOF
done
