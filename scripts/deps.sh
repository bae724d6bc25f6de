#!/usr/bin/env bash
# Installs, with apt-get, the Debian 12 packages isomend needs and that are missing.
# Usage: scripts/deps.sh [build|test|all]   (default all)
#   build: compilers, CMake, zlib, OpenImageIO, GDCM, libnifti2, libtiff/OpenEXR/libpng and patchelf
#          (the portable importer the Blender add-on carries), Qt/MeshLab headers' needs,
#          Open MPI (isomend-mpi and its tests)
#   test:  build + the peers and hosts the tests drive (VTK, scikit-image,
#          MeshLab, Blender, Xvfb, pytest, pydicom, gdcmconv) and mmdebstrap
#          (the Debian 13 root of scripts/trixie-root.sh)
set -euo pipefail
what="${1:-all}"
BUILD_PKGS=(build-essential cmake pkg-config zlib1g-dev
  libopenimageio-dev openimageio-tools libgdcm-dev libnifti2-dev
  libtiff-dev libopenexr-dev libpng-dev patchelf
  qtbase5-dev libqt5opengl5-dev libglew-dev libeigen3-dev dpkg-dev meshlab
  python3-numpy libopenmpi-dev openmpi-bin)
TEST_PKGS=(python3-pytest python3-vtk9 python3-skimage python3-openimageio python3-tifffile
  xvfb xauth blender libtiff-tools libopenvdb-dev python3-openvdb python3-nibabel
  python3-scipy mmdebstrap python3-pydicom libgdcm-tools
  libmeshoptimizer-dev)
pkgs=("${BUILD_PKGS[@]}")
[ "$what" = build ] || pkgs+=("${TEST_PKGS[@]}")
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "[deps] installing: ${missing[*]}" >&2
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO=sudo
  $SUDO apt-get -o DPkg::Lock::Timeout=600 update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get -o DPkg::Lock::Timeout=600 install -y -qq \
    --no-install-recommends "${missing[@]}" >/dev/null
fi
