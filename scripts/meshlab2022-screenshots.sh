#!/usr/bin/env bash
# Recreates the README's MeshLab screenshots (docs/img/meshlab-*.png) from
# MeshLab 2022.02 in the Debian 13 root: tests/meshlab/test_gui_2022.py drives
# the GUI under Xvfb (Filters > Create New Mesh Layer > Isosurface from Slice
# Stack (isomend), source and iso typed in, Apply) on the T1 MRI of
# scripts/get-test-data.sh, checks the exported mesh against the CLI's, and
# writes the cropped menu, dialog and result captures.
# (MeshLab 2020.09: scripts/meshlab-screenshots.sh.)
#
# Usage: scripts/meshlab2022-screenshots.sh [OUT_DIR]   (default docs/img)
# Needs the trixie build of scripts/test-trixie.sh (build-trixie/build).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-docs/img}"
mkdir -p "$out" build-trixie/screenshots
[ -f build-trixie/build/CMakeCache.txt ] || { echo "meshlab2022-screenshots: run scripts/test-trixie.sh first" >&2; exit 1; }
bash scripts/trixie-run.sh -b "$(cd "$out" && pwd):/out" -- bash -c '
set -euo pipefail
bash /src/scripts/get-test-data.sh mri_t1_small >&2
tiff=/work/home/.cache/isomend/mri_t1_small/tiff
iso=$(/work/build/io/isomend info "$tiff" --json - | python3 -c "import json,sys; print(json.load(sys.stdin)[\"suggested_iso\"])")
ISOMEND_XVFB_SCREEN=1280x1024x24 python3 /src/tests/meshlab/with_xvfb.py python3 /src/tests/meshlab/test_gui_2022.py \
  --meshlab /usr/bin/meshlab --plugin /work/build/meshlab_filter/plugins/libfilter_isomend.so \
  --cli /work/build/io/isomend --work /work/screenshots/run --source "$tiff" --iso "$iso" \
  --screenshots /work/screenshots
cp /work/screenshots/meshlab-menu.png /work/screenshots/meshlab-dialog.png /work/screenshots/meshlab-result.png /out/
'
echo "meshlab2022-screenshots: wrote $out/meshlab-menu.png meshlab-dialog.png meshlab-result.png" >&2
