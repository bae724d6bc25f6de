#!/usr/bin/env bash
# The Debian 13 ("trixie") part of scripts/test.sh: builds (or reuses) the
# trixie root of scripts/trixie-root.sh, configures and builds the project
# INSIDE it (build-trixie/build, against trixie's OpenImageIO 2.5, Qt and
# MeshLab 2022.02 headers), runs the tests labelled "trixie" (the newer
# hosts: MeshLab 2022.02, Blender 4.3) and "sanitize" (the C tests of the
# core, the command line and the importer) there, and finally runs the
# Debian 12 build's tests labelled "after_trixie" on this machine (tests
# that take something the trixie build made, e.g. its add-on package).
# See docs/testing-trixie.md.
#
# Usage: scripts/test-trixie.sh [CTEST_ARG...]
#   extra arguments go to the ctest inside the root (e.g. -R meshlab2022);
#   the "after_trixie" tests are skipped when any are given.
# Environment:
#   JOBS                 parallel build jobs and tests (default: nproc)
#   ISOMEND_HOST_BUILD   the Debian 12 build tree (default build/); mounted
#                        read-only at /host-build inside the root when it exists
#   ISOMEND_TRIXIE_WORK  the work folder, /work inside (default build-trixie/)
# Exit status: 0 when every part passed.
set -euo pipefail
cd "$(dirname "$0")/.."
JOBS="${JOBS:-$(nproc)}"
work="${ISOMEND_TRIXIE_WORK:-build-trixie}"
host_build="${ISOMEND_HOST_BUILD:-build}"
t0=$(date +%s)

bash scripts/trixie-root.sh >/dev/null
t_root=$(( $(date +%s) - t0 ))

binds=()
hb=""
if [ -d "$host_build" ]; then
  binds+=(-r "$(cd "$host_build" && pwd):/host-build")
  hb=/host-build
fi
mkdir -p "$work"
set +e
bash scripts/trixie-run.sh -w "$work" "${binds[@]}" -- /bin/bash -c '
set -euo pipefail
jobs="$1" hb="$2"; shift 2
cmake -S /src -B /work/build -DCMAKE_BUILD_TYPE=RelWithDebInfo -DISOMEND_WERROR=ON \
  -DISOMEND_MESHLAB_REQUIRED=ON -DISOMEND_BUILD_BENCH=OFF \
  -DISOMEND_HOST_BUILD_DIR="$hb" >/work/cmake.log \
  || { cat /work/cmake.log; exit 1; }
grep -E "^-- (meshlab|tests/|Blender|isomend)" /work/cmake.log || true
cmake --build /work/build -j "$jobs"
ctest --test-dir /work/build --output-on-failure -j "$jobs" --timeout 1500 \
  -L "^(trixie|sanitize)\$" "$@"
' bash "$JOBS" "$hb" "$@"
rc_in=$?
set -e
t_in=$(( $(date +%s) - t0 - t_root ))

rc_after=0
if [ $# -eq 0 ] && [ -f "$host_build/CTestTestfile.cmake" ] &&
   ctest --test-dir "$host_build" -N -L after_trixie | grep -qE 'Total Tests: [1-9]'; then
  set +e
  ISOMEND_TRIXIE_BUILD="$(cd "$work" && pwd)/build" \
    ctest --test-dir "$host_build" --output-on-failure -j "$JOBS" --timeout 1500 -L after_trixie
  rc_after=$?
  set -e
fi
echo "test-trixie: root ${t_root} s, build and tests in the root ${t_in} s (exit $rc_in)," \
     "after_trixie exit $rc_after, total $(( $(date +%s) - t0 )) s"
[ $rc_in -eq 0 ] && [ $rc_after -eq 0 ]
