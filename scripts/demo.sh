#!/usr/bin/env bash
# The README's main command: installs what is missing, builds the isomend
# command line, and runs the thesis's experiments on embedded data:
#   - F1 and F2 (thesis chapter 5.2) with plain marching cubes, Durst's
#     method and the thesis method (DMC): Table-2 statistics, the triangles
#     from the table versus from mending, and the continuity check of each;
#   - the bundled MRI sample (samples/anatomical.nrrd, MIT licence), padded,
#     with DMC, at the suggested (Otsu) iso level.
# Meshes go to out/ (PLY, viewable in MeshLab/Blender/ParaView).
#
# Environment: BUILD_DIR (default build), OUT_DIR (default out), JOBS (default nproc).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR="${BUILD_DIR:-build}"
OUT_DIR="${OUT_DIR:-out}"
JOBS="${JOBS:-$(nproc)}"

bash scripts/deps.sh build
echo "== building the isomend command line in $BUILD_DIR/"
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$BUILD_DIR" -j "$JOBS" --target isomend_cli >/dev/null
ISOMEND="$BUILD_DIR/io/isomend"
mkdir -p "$OUT_DIR"
"$ISOMEND" --version

banner() { printf '\n======== %s ========\n' "$*"; }

# ---- thesis chapter 5.2: F1 and F2 with the three methods -------------------
for f in f1 f2; do
  "$ISOMEND" sample "$f" -o "$OUT_DIR/$f.nrrd" --quiet
  for m in mc durst dmc; do
    banner "$(echo "$f" | tr a-z A-Z), method $m"
    "$ISOMEND" extract "$OUT_DIR/$f.nrrd" --iso 0 --method "$m" --stats \
      -o "$OUT_DIR/${f}_$m.ply" --json "$OUT_DIR/${f}_$m.json"
  done
done

# ---- a real volume: the bundled MRI sample -----------------------------------
banner "samples/anatomical.nrrd (MRI, 33x41x25 int16), padded, dmc"
"$ISOMEND" info samples/anatomical.nrrd
"$ISOMEND" extract samples/anatomical.nrrd --pad --stats \
  -o "$OUT_DIR/anatomical_dmc.ply" --json "$OUT_DIR/anatomical_dmc.json"
banner "the same with plain marching cubes, for comparison"
"$ISOMEND" extract samples/anatomical.nrrd --pad --method mc --quiet \
  -o "$OUT_DIR/anatomical_mc.ply" --json "$OUT_DIR/anatomical_mc.json"
"$ISOMEND" check "$OUT_DIR/anatomical_mc.ply" || echo "(plain MC leaves holes: exit status $?)"

# ---- slice stacks (io engineer) -----------------------------------------------
# >>> SLICE-STACK STEP (io engineer): the same MRI as a folder of TIFF slices
if cmake --build "$BUILD_DIR" -j "$JOBS" --target isomend_io >/dev/null 2>&1; then
  banner "slice stack: samples/anatomical.nrrd written as 25 TIFF slices, then read back"
  rm -rf "$OUT_DIR/anatomical_slices"
  /usr/bin/python3 io/slices/tools/nrrd_to_tiff_slices.py samples/anatomical.nrrd "$OUT_DIR/anatomical_slices"
  "$ISOMEND" info "$OUT_DIR/anatomical_slices"
  "$ISOMEND" extract "$OUT_DIR/anatomical_slices" --pad \
    -o "$OUT_DIR/anatomical_slices_dmc.ply" --json "$OUT_DIR/anatomical_slices_dmc.json"
  banner "a printf pattern with a range: slices 5, 7, ..., 19 only"
  "$ISOMEND" extract "$OUT_DIR/anatomical_slices/slice_%04d.tif" --first 5 --count 8 --step 2 \
    --pad --quiet -o "$OUT_DIR/anatomical_slices_part.ply" --json "$OUT_DIR/anatomical_slices_part.json"
  echo "wrote $OUT_DIR/anatomical_slices_part.ply"
else
  banner "slice stacks skipped: the OpenImageIO importer (isomend_io) is not built"
fi
# <<< SLICE-STACK STEP

banner "summary"
echo "meshes and JSON reports in $OUT_DIR/:"
ls -1 "$OUT_DIR"
