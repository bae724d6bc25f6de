#!/usr/bin/env bash
# get-test-data.sh - fetch a REAL volume shipped inside a Debian 12 package and
# turn it into the inputs isomend's importer tests use:
#
#   $OUT/<name>/tiff/slice_0000.tif ...  one single-channel TIFF per z slice, the
#                                        volume's own sample type, written by
#                                        tifffile (not by OpenImageIO, which reads
#                                        them), with ImageJ spacing metadata
#   $OUT/<name>/<name>.raw               little-endian raw, x fastest, then y, then z
#   $OUT/<name>/<name>.json              dims (x,y,z), dtype, spacing, provenance
#
# Datasets:
#   mri_t1_small  T1 MRI of a head, KmeansTest_T1UCharRaw.nii.gz from
#                 insighttoolkit5-examples (ITK example data, Apache-2.0)
#   mri_tiny      anatomical.nii from python3-nibabel's test data (MIT)
#
# Only the Debian archive is used (apt-get download: no installation, no
# root needed once the apt lists exist).  Conversion needs Debian's python3
# with numpy, nibabel and tifffile (python3-numpy python3-nibabel python3-tifffile).
# Mapping: slice k = z index k; TIFF column = x, TIFF row = y (no flips), so the
# stack and the raw file describe the same samples.
#
# Usage: scripts/get-test-data.sh [--out DIR] [--force] [NAME ...]   (default: mri_t1_small)
#   --force converts again even if $OUT/NAME exists
# Env:   ISOMEND_TESTDATA (default ${XDG_CACHE_HOME:-$HOME/.cache}/isomend)
# Exit status 1 with a message naming the step when anything fails.
set -euo pipefail

OUT="${ISOMEND_TESTDATA:-${XDG_CACHE_HOME:-$HOME/.cache}/isomend}"
SETS=()
FORCE=0
while [ $# -gt 0 ]; do
  case "$1" in
    --out) OUT="$2"; shift ;;
    --force) FORCE=1 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d'; exit 0 ;;
    -*) echo "get-test-data: unknown option $1" >&2; exit 1 ;;
    *) SETS+=("$1") ;;
  esac
  shift
done
[ ${#SETS[@]} -eq 0 ] && SETS=(mri_t1_small)
PY=/usr/bin/python3
log() { printf '[get-test-data] %s\n' "$*" >&2; }
die() { log "ERROR: $*"; exit 1; }

for s in "${SETS[@]}"; do
  case "$s" in mri_t1_small|mri_tiny) ;; *) die "unknown dataset '$s' (known: mri_t1_small mri_tiny)";; esac
done
[ -x "$PY" ] || die "$PY not found"
for m in numpy nibabel tifffile; do
  "$PY" -c "import $m" 2>/dev/null || die "python module '$m' missing: apt-get install python3-$m"
done
command -v dpkg-deb >/dev/null || die "dpkg-deb not found (not a Debian system?)"
command -v apt-get >/dev/null || die "apt-get not found: cannot download the Debian package"

CACHE="$OUT/.cache"
mkdir -p "$CACHE/deb" "$CACHE/x"
[ "$(id -u)" = 0 ] && chmod 0777 "$CACHE/deb"   # apt's _apt sandbox user writes there

# fetch_deb PKG: downloads (once) and extracts (once) PKG into $CACHE/x/PKG
fetch_deb() {
  local pkg="$1" deb x="$CACHE/x/$1"
  deb=$(ls "$CACHE/deb/${pkg}"_*.deb 2>/dev/null | head -n1 || true)
  if [ -z "$deb" ]; then
    if ! apt-cache show "$pkg" >/dev/null 2>&1; then
      [ "$(id -u)" = 0 ] || die "apt does not know $pkg; run 'apt-get update' as root first"
      log "apt-get update"
      apt-get -o DPkg::Lock::Timeout=600 update -qq >&2 || die "apt-get update failed"
    fi
    log "apt-get download $pkg"
    (cd "$CACHE/deb" && apt-get -o Acquire::Retries=3 download -qq "$pkg" >&2) \
      || die "apt-get download $pkg failed (no access to the Debian archive?)"
    deb=$(ls "$CACHE/deb/${pkg}"_*.deb | head -n1)
  fi
  if [ ! -d "$x" ]; then
    rm -rf "$x.tmp"; mkdir -p "$x.tmp"
    dpkg-deb -x "$deb" "$x.tmp" || die "cannot unpack $deb"
    mv "$x.tmp" "$x"
  fi
  dpkg-deb -f "$deb" Version > "$x.version"
}

for s in "${SETS[@]}"; do
  case "$s" in
    mri_t1_small) fetch_deb insighttoolkit5-examples ;;
    mri_tiny) fetch_deb python3-nibabel ;;
  esac
done

RD_OUT="$OUT" RD_CACHE="$CACHE" RD_FORCE="$FORCE" "$PY" - "${SETS[@]}" <<'PYEOF'
import hashlib, json, os, shutil, sys
import numpy as np
import nibabel as nib
import tifffile

OUT = os.environ["RD_OUT"]; X = os.path.join(os.environ["RD_CACHE"], "x")
SETS = {
    "mri_t1_small": dict(pkg="insighttoolkit5-examples",
                         path="usr/share/doc/insighttoolkit5-examples/examples/Data/KmeansTest_T1UCharRaw.nii.gz",
                         sha256="e0e5975587f3f7916804bdd317c493cdb99cdb3703bf2671d458528f62510327",
                         title="MRI head T1 (ITK example data)", license="Apache-2.0 (ITK)"),
    "mri_tiny": dict(pkg="python3-nibabel",
                     path="usr/lib/python3/dist-packages/nibabel/tests/data/anatomical.nii",
                     sha256="1c089f37b6597a38bb4157a1e1b3f7f13f1bc9d4e7a8cfdfaf91d85cd8f66594",
                     title="MRI head T1, tiny (nibabel test data)", license="MIT (nibabel)"),
}

def sha256(p):
    h = hashlib.sha256()
    with open(p, "rb") as f:
        for b in iter(lambda: f.read(1 << 20), b""):
            h.update(b)
    return h.hexdigest()

FORCE = os.environ.get("RD_FORCE") == "1"
for name in sys.argv[1:]:
    d = SETS[name]
    if not FORCE and os.path.exists(os.path.join(OUT, name, name + ".json")):
        print("[get-test-data] %s: already converted in %s (--force redoes it)" % (name, os.path.join(OUT, name)),
              file=sys.stderr)
        continue
    src = os.path.join(X, d["pkg"], d["path"])
    if not os.path.exists(src):
        sys.exit("[get-test-data] ERROR: %s not found in the package %s" % (d["path"], d["pkg"]))
    img = nib.load(src)
    a = np.asarray(img.dataobj.get_unscaled())
    while a.ndim > 3 and a.shape[-1] == 1:
        a = a[..., 0]
    if a.ndim != 3:
        sys.exit("[get-test-data] ERROR: %s is not a 3D volume (shape %s)" % (src, a.shape))
    a = a.astype(a.dtype.newbyteorder("="))           # array indexed [x, y, z]
    sp = [float(z) for z in img.header.get_zooms()[:3]]
    nx, ny, nz = a.shape
    final = os.path.join(OUT, name); tmp = final + ".tmp"
    shutil.rmtree(tmp, ignore_errors=True); os.makedirs(os.path.join(tmp, "tiff"))
    raw = os.path.join(tmp, name + ".raw")
    np.ascontiguousarray(a.transpose(2, 1, 0)).astype(a.dtype.newbyteorder("<")).tofile(raw)
    for k in range(nz):
        # ImageJ metadata: pixels per unit in the resolution tags, z spacing in the description
        tifffile.imwrite(os.path.join(tmp, "tiff", "slice_%04d.tif" % k), np.ascontiguousarray(a[:, :, k].T),
                         photometric="minisblack", metadata=None, resolution=(1 / sp[0], 1 / sp[1]),
                         description="ImageJ=1.11a\nunit=mm\nspacing=%r\n" % sp[2])
    got = sha256(src)
    meta = dict(name=name, title=d["title"], dims_xyz=[nx, ny, nz], dtype=a.dtype.name, byte_order="little",
                spacing_xyz_mm=sp, value_range=[float(a.min()), float(a.max())],
                raw=name + ".raw", tiff=dict(dir="tiff", pattern="slice_%04d.tif", count=nz),
                source=dict(registry="debian", package=d["pkg"],
                            version=open(os.path.join(X, d["pkg"] + ".version")).read().strip(),
                            path_in_package="/" + d["path"], license=d["license"], sha256=got,
                            sha256_matches_expected=(got == d["sha256"])))
    with open(os.path.join(tmp, name + ".json"), "w") as f:
        json.dump(meta, f, indent=1)
    shutil.rmtree(final, ignore_errors=True); os.rename(tmp, final)
    print("[get-test-data] %s: %dx%dx%d %s spacing %s -> %s" % (name, nx, ny, nz, a.dtype.name,
          ",".join("%g" % s for s in sp), final), file=sys.stderr)
PYEOF
log "done: $OUT"
