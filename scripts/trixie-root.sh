#!/usr/bin/env bash
# Builds (or reuses) a Debian 13 "trixie" root file system for testing
# isomend in the hosts people run today: MeshLab 2022.02, Blender 4.3,
# OpenImageIO 2.5.  The machine's own apt configuration is never touched:
# mmdebstrap (a Debian 12 package) downloads from the mirror that the
# machine's Debian sources already name, checked against Debian's archive
# keyring, into a folder of ours.
#
# Usage: scripts/trixie-root.sh [--print]
#   Prints the root's path on stdout when it is ready.
# Environment:
#   ISOMEND_TRIXIE_ROOT   where the root lives
#                         (default ${XDG_CACHE_HOME:-$HOME/.cache}/isomend/trixie-root)
#   ISOMEND_TRIXIE_MIRROR the Debian mirror (default: the first deb.debian.org-style
#                         URI of the machine's sources, else http://deb.debian.org/debian)
#
# The root is reused when its package list (.isomend-packages, written when
# it is complete) contains every package of this script's list, so worktrees
# whose lists differ do not rebuild it in turn.  Otherwise it is built again
# with the UNION of both lists (packages are only ever added; delete the root
# to drop one), under a temporary name that is renamed when complete, so an
# interrupted build never leaves a root that looks finished.  One build at a
# time (flock on ROOT.build.lock); the new root replaces the old one only
# when no scripts/trixie-run.sh command is using it (they hold ROOT.lock
# shared).  Needs root (mmdebstrap's root mode, chroot later).
# Run commands inside it with scripts/trixie-run.sh.
set -euo pipefail
cd "$(dirname "$0")/.."

die() { echo "trixie-root: $*" >&2; exit 1; }

# What the tests need inside the root: the build tools and the libraries the
# project builds against there, the two hosts, Xvfb, and Python with numpy.
# Add packages rather than remove them: other tests share the root.
# mmdebstrap installs no Recommends: the three libraries after meshlab are
# those its GUI needs to load every stock plugin (else a warning box).
PKGS=(build-essential cmake pkg-config zlib1g-dev patchelf file
  libopenimageio-dev openimageio-tools libtiff-dev libtiff-tools libopenexr-dev libgdcm-dev libgdcm-tools
  libnifti2-dev
  qtbase5-dev libqt5opengl5-dev libglew-dev libeigen3-dev
  meshlab blender
  lib3ds-1-3 libmuparser2v5 libopenctm1
  xvfb xauth x11-apps imagemagick xdotool
  python3 python3-numpy python3-pytest python3-pydicom python3-tifffile
  python3-openimageio python3-nibabel python3-openvdb libpng-dev
  ca-certificates dpkg-dev)

[ "$(id -u)" = 0 ] || die "must run as root (mmdebstrap root mode and chroot)"
root="${ISOMEND_TRIXIE_ROOT:-${XDG_CACHE_HOME:-$HOME/.cache}/isomend/trixie-root}"
want="$(printf '%s\n' "${PKGS[@]}" | sort -u)"
ready() {
  [ -f "$root/.isomend-complete" ] && [ -f "$root/.isomend-packages" ] &&
    [ -z "$(comm -23 <(echo "$want") <(sort -u "$root/.isomend-packages"))" ]
}
if ready; then
  echo "$root"
  exit 0
fi
# One build at a time (two worktrees may ask at once): the second waits and
# then finds the root ready.
mkdir -p "$(dirname "$root")"
exec 9>"$root.build.lock"
flock 9
if ready; then
  echo "$root"
  exit 0
fi
all="$want"
if [ -f "$root/.isomend-packages" ]; then
  all="$( { echo "$want"; cat "$root/.isomend-packages"; } | sort -u)"
fi

if ! command -v mmdebstrap >/dev/null; then
  SUDO=""
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get -o DPkg::Lock::Timeout=600 install -y -qq \
    --no-install-recommends mmdebstrap >/dev/null \
    || { apt-get -o DPkg::Lock::Timeout=600 update -qq &&
         DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -qq \
           --no-install-recommends mmdebstrap >/dev/null; } \
    || die "cannot install mmdebstrap"
fi

mirror="${ISOMEND_TRIXIE_MIRROR:-}"
if [ -z "$mirror" ]; then
  mirror="$(grep -hoE '^(URIs:|deb) +(\[[^]]*\] +)?https?://[^ ]+/debian/?( |$)' \
      /etc/apt/sources.list.d/*.sources /etc/apt/sources.list 2>/dev/null \
    | grep -oE 'https?://[^ ]+' | head -n 1 || true)"
  mirror="${mirror:-http://deb.debian.org/debian}"
fi
keyring=/usr/share/keyrings/debian-archive-keyring.gpg
[ -f "$keyring" ] || die "$keyring missing (package debian-archive-keyring)"

tmp="$root.tmp.$$"
rm -rf "$tmp"
trap 'rm -rf "$tmp"' EXIT
start=$(date +%s)
echo "trixie-root: building $root from $mirror (2-3 minutes here, about 2 GB)" >&2
list="$(echo "$all" | paste -sd, -)"
mmdebstrap --quiet --mode=root --variant=apt --include="$list" \
  --aptopt='Acquire::Retries "3"' \
  --dpkgopt='path-exclude=/usr/share/doc/*' --dpkgopt='path-exclude=/usr/share/man/*' \
  trixie "$tmp" "deb [signed-by=$keyring] $mirror trixie main" >&2 \
  || die "mmdebstrap failed"
# A deb-src twin for `apt-get source meshlab` inside the root.
echo "deb-src [signed-by=$keyring] $mirror trixie main" >"$tmp/etc/apt/sources.list.d/src.list"
# Mount points of trixie-run.sh (it mounts the root read-only).
mkdir -p "$tmp/src" "$tmp/work" "$tmp/host-build"
touch "$tmp/etc/resolv.conf"
echo "$all" >"$tmp/.isomend-packages"
date -u +%FT%TZ >"$tmp/.isomend-complete"
# Swap when no trixie-run.sh command uses the old root (they hold ROOT.lock
# shared); the old root is moved aside before it is deleted, so the new one
# appears at once.
exec 8>"$root.lock"
if ! flock -n 8; then
  echo "trixie-root: waiting for the commands running in the old root to end" >&2
  flock 8
fi
old="$root.old.$$"
[ ! -e "$root" ] || mv "$root" "$old"
mv "$tmp" "$root"
flock -u 8
rm -rf "$old"
trap - EXIT
echo "trixie-root: ready in $(( $(date +%s) - start )) s" >&2
echo "$root"
