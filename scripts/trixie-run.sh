#!/usr/bin/env bash
# Runs a command inside the Debian 13 root of scripts/trixie-root.sh, with
# the project mounted at /src (read-only) and a work folder at /work
# (read-write).  The mounts live in a private mount namespace (unshare -m), so
# they vanish when the command ends, whatever way it ends.
#
# Usage: scripts/trixie-run.sh [-w WORKDIR] [-b H:C]... [-r H:C]... [--rw] -- CMD [ARG...]
#   -w WORKDIR   host folder mounted read-write at /work (default: build-trixie)
#   -b H:C       bind-mount the host folder H at C inside the root (read-write)
#   -r H:C       the same, read-only
#   --rw         leave the root itself writable (maintenance only)
# The command runs as root with HOME=/work/home, TMPDIR=/work/tmp,
# XDG_RUNTIME_DIR=/run/user/0 and a fresh tmpfs at /tmp, /run and /var/tmp.
#
# The root is shared by every worktree and reused between runs, so it is
# mounted read-only: a test cannot change what the next run starts from.
# apt's lists and package cache live in WORKDIR/apt (so `apt-get update` and
# `apt-get download` work inside), DNS comes from the host's resolv.conf.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
work="$here/build-trixie"
binds=()
root_mode=ro
while [ $# -gt 0 ]; do
  case "$1" in
    -w) work="$2"; shift 2 ;;
    -b) binds+=("rw:$2"); shift 2 ;;
    -r) binds+=("ro:$2"); shift 2 ;;
    --rw) root_mode=rw; shift ;;
    --) shift; break ;;
    *) break ;;
  esac
done
[ $# -ge 1 ] || { echo "usage: $0 [-w WORKDIR] [-b H:C]... [-r H:C]... [--rw] -- CMD [ARG...]" >&2; exit 2; }
root="$(bash "$here/scripts/trixie-root.sh")"
# Held (shared) until the command ends: trixie-root.sh replaces the root only
# when no command is using it.
exec 8>"$root.lock"
flock -s 8
mkdir -p "$work/home" "$work/tmp" "$work/apt/lists/partial" "$work/apt/cache/archives/partial"
work="$(cd "$work" && pwd)"
for b in "${binds[@]}"; do
  h="${b#*:}"; h="${h%%:*}"
  [ -d "$h" ] || { echo "trixie-run: $h is not a folder" >&2; exit 2; }
done

# The inner script gets its arguments positionally: root, project, work, root
# mode, the number of extra binds, the binds, then the command.
exec unshare -m --propagation private bash -s -- "$root" "$here" "$work" "$root_mode" \
  "${#binds[@]}" "${binds[@]}" "$@" <<'INNER'
set -euo pipefail
root="$1" src="$2" work="$3" mode="$4" nb="$5"; shift 5
bind() { # bind HOSTPATH TARGET ro|rw
  mount --bind "$1" "$2"
  [ "$3" = rw ] || mount -o remount,bind,ro "$2"
}
# Mount points first (the root becomes read-only next).
mkdir -p "$root/src" "$root/work" "$root/tmp" "$root/run" "$root/var/tmp"
[ -e "$root/etc/resolv.conf" ] || touch "$root/etc/resolv.conf"
extra=()
for ((i = 0; i < nb; i++)); do
  b="$1"; shift
  m="${b%%:*}" b="${b#*:}"
  h="${b%%:*}" c="${b#*:}"
  mkdir -p "$root$c"
  extra+=("$m" "$h" "$c")
done
bind "$root" "$root" "$mode"
mount -t proc proc "$root/proc"
mount --rbind /dev "$root/dev"
mount --rbind /sys "$root/sys"
bind "$src" "$root/src" ro
bind "$work" "$root/work" rw
bind "$work/apt/lists" "$root/var/lib/apt/lists" rw
bind "$work/apt/cache" "$root/var/cache/apt" rw
mount -t tmpfs tmpfs "$root/tmp"
mount -t tmpfs tmpfs "$root/run"
mkdir -m 700 -p "$root/run/user/0"
mount -t tmpfs tmpfs "$root/var/tmp"
[ -f /etc/resolv.conf ] && bind /etc/resolv.conf "$root/etc/resolv.conf" ro
for ((i = 0; i < ${#extra[@]}; i += 3)); do
  bind "${extra[i + 1]}" "$root${extra[i + 2]}" "${extra[i]}"
done
exec chroot "$root" /usr/bin/env -i PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
  HOME=/work/home TMPDIR=/work/tmp XDG_RUNTIME_DIR=/run/user/0 LANG=C.UTF-8 "$@"
INNER
