#!/usr/bin/env bash
# The README's test command: installs what is missing, builds everything with
# warnings as errors, runs every test (ctest), then rebuilds the C core, the
# command line, the slice-stack importer and their tests under AddressSanitizer
# + UBSan and runs the tests labelled "sanitize" again, and finally the Debian
# 13 part, scripts/test-trixie.sh (MeshLab 2022.02, Blender 4.3, OpenImageIO
# 2.5 in a trixie root file system; ISOMEND_TRIXIE=0 leaves it out).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh all
JOBS="${JOBS:-$(nproc)}"
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo -DISOMEND_WERROR=ON >/dev/null
cmake --build build -j "$JOBS"
set +e
ctest --test-dir build --output-on-failure -j "$JOBS" --timeout 1500 -LE after_trixie
rc1=$?
set -e
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DISOMEND_SANITIZE=ON -DISOMEND_WERROR=ON \
  -DISOMEND_BUILD_MESHLAB=OFF -DISOMEND_BUILD_BLENDER=OFF \
  -DISOMEND_PEER_TESTS=OFF >/dev/null
cmake --build build-asan -j "$JOBS"
set +e
ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --test-dir build-asan --output-on-failure -j "$JOBS" -L sanitize --timeout 1500
rc2=$?
rc3=0
if [ "${ISOMEND_TRIXIE:-1}" != 0 ]; then
  JOBS="$JOBS" bash scripts/test-trixie.sh
  rc3=$?
else
  echo "test.sh: the Debian 13 part is left out (ISOMEND_TRIXIE=0)"
fi
set -e
echo "test.sh: release suite exit $rc1, sanitizer suite exit $rc2, Debian 13 part exit $rc3"
[ $rc1 -eq 0 ] && [ $rc2 -eq 0 ] && [ $rc3 -eq 0 ]
