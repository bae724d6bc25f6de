#!/usr/bin/env bash
# Runs a command inside the Debian 13 root of scripts/trixie-root.sh, with
# the project mounted at /src (read-only) and a work folder at /work
# (read-write).  The mounts live in a private mount namespace (unshare -m), so
# they vanish when the command ends, whatever way it ends.
#
# Usage: scripts/trixie-run.sh [-w WORKDIR] [-b HOSTDIR:CHROOTDIR]... -- CMD [ARG...]
#   -w WORKDIR   host folder mounted read-write at /work (default: build-trixie)
#   -b H:C       bind-mount the host folder H at C inside the root as well
# The command runs as root with HOME=/work/home, TMPDIR=/work/tmp.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
work="$here/build-trixie"
binds=()
while [ $# -gt 0 ]; do
  case "$1" in
    -w) work="$2"; shift 2 ;;
    -b) binds+=("$2"); shift 2 ;;
    --) shift; break ;;
    *) break ;;
  esac
done
[ $# -ge 1 ] || { echo "usage: $0 [-w WORKDIR] [-b H:C]... -- CMD [ARG...]" >&2; exit 2; }
root="$(bash "$here/scripts/trixie-root.sh")"
mkdir -p "$work/home" "$work/tmp"
work="$(cd "$work" && pwd)"

# The inner script gets its arguments positionally: root, project, work, the
# number of extra binds, the binds, then the command.
exec unshare -m --propagation private bash -s -- "$root" "$here" "$work" "${#binds[@]}" \
  "${binds[@]}" "$@" <<'INNER'
set -euo pipefail
root="$1" src="$2" work="$3" nb="$4"; shift 4
mount -t proc proc "$root/proc"
mount --rbind /dev "$root/dev"
mount --rbind /sys "$root/sys"
mkdir -p "$root/src" "$root/work" "$root/tmp"
mount --bind "$src" "$root/src"
mount -o remount,bind,ro "$root/src"
mount --bind "$work" "$root/work"
mount -t tmpfs tmpfs "$root/tmp"
for ((i = 0; i < nb; i++)); do
  h="${1%%:*}" c="${1#*:}"; shift
  mkdir -p "$root$c"
  mount --bind "$h" "$root$c"
done
cp /etc/resolv.conf "$root/etc/resolv.conf" 2>/dev/null || true
exec chroot "$root" /usr/bin/env -i PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
  HOME=/work/home TMPDIR=/work/tmp LANG=C.UTF-8 "$@"
INNER
