#!/usr/bin/env bash
# Fetches MeshLab's source package from Debian's archive and unpacks it, so
# that the plugin can be compiled against the headers of the MeshLab that is
# installed (Debian ships no meshlab-dev package).  The sources are never
# committed: they live in a cache folder, by default in the build tree.
#
# Usage: fetch-meshlab-sources.sh CACHE_DIR [VERSION [SUITE]]
#   CACHE_DIR  where to keep the unpacked tree
#   VERSION    Debian version of the source package (default: the installed
#              meshlab package's version, e.g. 2020.09+dfsg1-2)
#   SUITE      take the package from this Debian suite of the same archive
#              instead of the system's suites (e.g. "trixie" for MeshLab
#              2022.02, used to compile-check the newer-API adapter).  Only the
#              upstream tarball is unpacked then (no Debian patches), as when
#              the mirror lacks the package's .dsc or Debian tarball.
# Prints the unpacked tree's path on stdout.
#
# Idempotent: a finished tree (marked by CACHE_DIR/<tree>/.isomend-complete)
# is reused without touching the network.  A tree is unpacked under a
# temporary name and renamed when complete, so an interrupted run never
# leaves a half tree that looks finished.
#
# Root is not needed and nothing is written under /etc or /var: apt runs
# with a private source list (the deb-src twin of the system's Debian
# entries), a private list/cache folder inside CACHE_DIR and no locking, so
# it does not interfere with the system's apt.  apt checks the downloaded
# files against the hashes of the signed Sources index (Signed-By keyring);
# dpkg-source then unpacks them and applies Debian's patches.  Afterwards only
# the unpacked tree is kept.
# Measured on this machine: 3-9 s (10 MB Sources index, 11.6 MB tarball,
# 45 MB unpacked).
set -euo pipefail

die() { echo "fetch-meshlab-sources: $*" >&2; exit 1; }

[ $# -ge 1 ] && [ $# -le 3 ] || die "usage: $0 CACHE_DIR [VERSION [SUITE]]"
cache="$1"
version="${2:-}"
suite="${3:-}"
if [ -z "$version" ]; then
  version="$(dpkg-query -W -f='${Version}' meshlab 2>/dev/null || true)"
  [ -n "$version" ] || die "the meshlab package is not installed and no VERSION was given"
fi
upstream="${version#*:}"; upstream="${upstream%-*}"   # 2020.09+dfsg1
tree="$cache/meshlab-$upstream"

if [ -f "$tree/.isomend-complete" ]; then
  echo "$tree"
  exit 0
fi

for tool in apt-get dpkg-source tar; do
  command -v "$tool" >/dev/null || die "'$tool' not found (install apt and dpkg-dev)"
done

mkdir -p "$cache"
cache="$(cd "$cache" && pwd)"
tree="$cache/meshlab-$upstream"
apt_dir="$cache/apt"
mkdir -p "$apt_dir/parts" "$apt_dir/lists/partial" "$apt_dir/cache/archives/partial"

# The deb-src twin of the system's Debian entries (deb822 and one-line
# forms); with SUITE, the first Debian entry with its suites replaced.
src_list="$apt_dir/parts/isomend-deb-src.sources"
oneline="$apt_dir/parts/isomend-deb-src.list"
: >"$src_list.tmp"
: >"$oneline.tmp"
for f in /etc/apt/sources.list.d/*.sources; do
  [ -f "$f" ] || continue
  grep -q 'debian' "$f" || continue
  if [ -n "$suite" ]; then
    # first stanza only (the main archive, not -security)
    awk 'BEGIN{RS=""; ORS="\n\n"} NR==1' "$f" \
      | sed -e 's/^Types:.*$/Types: deb-src/' -e "s/^Suites:.*\$/Suites: $suite/" >>"$src_list.tmp"
    break
  fi
  sed -e 's/^Types:.*$/Types: deb-src/' "$f" >>"$src_list.tmp"
  echo >>"$src_list.tmp"
done
if [ ! -s "$src_list.tmp" ]; then
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
    [ -f "$f" ] || continue
    grep -E '^[[:space:]]*deb[[:space:]].*debian' "$f" | sed -E 's/^[[:space:]]*deb[[:space:]]/deb-src /' \
      >>"$oneline.tmp" || true
  done
  if [ -n "$suite" ] && [ -s "$oneline.tmp" ]; then
    head -n 1 "$oneline.tmp" | awk -v s="$suite" '{ $3 = s; print }' >"$oneline.tmp2"
    mv "$oneline.tmp2" "$oneline.tmp"
  fi
fi
[ -s "$src_list.tmp" ] || [ -s "$oneline.tmp" ] || die "no Debian entry found in /etc/apt/sources.list*"
mv "$src_list.tmp" "$src_list"
mv "$oneline.tmp" "$oneline"

apt_opts=(-o "Dir::Etc::SourceList=/dev/null" -o "Dir::Etc::SourceParts=$apt_dir/parts"
  -o "Dir::State::Lists=$apt_dir/lists" -o "Dir::Cache=$apt_dir/cache"
  -o "Debug::NoLocking=1" -o "APT::Get::List-Cleanup=0")
if [ "$(id -u)" = 0 ]; then
  # apt drops to the _apt user to download; that user cannot write into a
  # build tree owned by root with a restrictive umask, so stay root.
  apt_opts+=(-o "APT::Sandbox::User=root")
fi

echo "fetch-meshlab-sources: downloading meshlab $version source package${suite:+ ($suite)} into $cache" >&2
apt-get "${apt_opts[@]}" -qq update >&2 || die "apt-get update (deb-src) failed"
dl="$cache/download"
rm -rf "$dl"
mkdir -p "$dl"
partial="$tree.partial.$$"
rm -rf "$partial"
# The Debian package (upstream tarball + Debian's patches), or with SUITE or
# when the mirror has no .dsc/.debian.tar for this version, the upstream
# tarball alone (the headers the plugin needs are upstream's).
tar_only="${suite:+1}"
if [ -z "$tar_only" ]; then
  if (cd "$dl" && apt-get "${apt_opts[@]}" -qq source --download-only "meshlab=$version" >&2); then
    dsc="$(ls "$dl"/meshlab_"${version#*:}".dsc 2>/dev/null | head -n 1)"
    [ -n "$dsc" ] || die "no .dsc for meshlab $version in $dl"
    dpkg-source -x "$dsc" "$partial" >"$cache/dpkg-source.log" 2>&1 \
      || { cat "$cache/dpkg-source.log" >&2; rm -rf "$partial"; die "dpkg-source -x $dsc failed"; }
  else
    echo "fetch-meshlab-sources: the source package meshlab=$version is incomplete on this" \
         "mirror; taking its upstream tarball alone (without Debian's patches)" >&2
    rm -rf "$dl" "$partial"
    mkdir -p "$dl"
    tar_only=1
  fi
fi
if [ -n "$tar_only" ]; then
  (cd "$dl" && apt-get "${apt_opts[@]}" -qq source --download-only --tar-only "meshlab=$version" >&2) \
    || die "apt-get source --tar-only meshlab=$version${suite:+ ($suite)} failed"
  orig="$(ls "$dl"/meshlab_*.orig.tar.* 2>/dev/null | head -n 1)"
  [ -n "$orig" ] || die "no upstream tarball for meshlab $version in $dl"
  mkdir -p "$partial"
  tar -xf "$orig" -C "$partial" --strip-components=1 || { rm -rf "$partial"; die "cannot unpack $orig"; }
fi
# 2020.09 keeps vcglib at the top, later versions in src/
[ -f "$partial/src/common/interfaces.h" ] || [ -f "$partial/src/common/plugins/interfaces/filter_plugin.h" ] \
  || { rm -rf "$partial"; die "unexpected tree: no MeshLab plugin interface header"; }
[ -d "$partial/vcglib/vcg" ] || [ -d "$partial/src/vcglib/vcg" ] \
  || { rm -rf "$partial"; die "unexpected tree: no vcglib/vcg"; }
echo "$version" >"$partial/.isomend-complete"
rm -rf "$tree"
mv "$partial" "$tree"
# Only the unpacked tree is needed from now on; drop the index and tarballs.
rm -rf "$apt_dir" "$dl" "$cache"/meshlab_*.orig.tar.* "$cache/dpkg-source.log"
echo "$tree"
