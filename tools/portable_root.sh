#!/bin/sh
# SPDX-License-Identifier: GPL-3.0-or-later
#
# A Debian 13 root file system without the build machine's libraries (`make test-portable`; root only).
#
#   portable_root.sh create ROOT WHEELS   debootstrap Debian 13 (Python 3.13) with only the X11 and GL
#                                         libraries bpy links, then a virtual environment /opt/venv with the
#                                         wheels in WHEELS (WHEELS/requirements.txt pins them; no network inside)
#   portable_root.sh run ROOT COMMAND...  run COMMAND inside ROOT
#
# `run` mounts /proc (Blender reads /proc/self/exe) in a mount namespace of its own, which ends with the
# command: nothing stays mounted under ROOT, so removing ROOT never reaches the host's /proc.
set -eu

MIRROR=${DEBIAN_MIRROR:-http://deb.debian.org/debian}
# What the bpy wheel links besides glibc (ldd on bpy/__init__.so).
BPY_LIBRARIES=libx11-6,libxext6,libxrender1,libxfixes3,libxi6,libxkbcommon0,libsm6,libice6,libgl1

usage() { echo "usage: $0 create ROOT WHEELS | run ROOT COMMAND..." >&2; exit 2; }
[ $# -ge 2 ] || usage
action=$1 root=$2
shift 2

case $action in
create)
    [ $# -eq 1 ] || usage
    wheels=$1
    rm -rf "$root.partial"
    debootstrap --variant=minbase --include=python3,python3-venv,$BPY_LIBRARIES trixie "$root.partial" "$MIRROR"
    mkdir -p "$root.partial/opt/wheels"
    cp "$wheels"/*.whl "$wheels/requirements.txt" "$root.partial/opt/wheels/"
    "$0" run "$root.partial" sh -c 'python3 -m venv /opt/venv &&
        /opt/venv/bin/pip install -q --no-index --find-links /opt/wheels -r /opt/wheels/requirements.txt'
    rm -rf "$root.partial/opt/wheels" "$root"
    mv "$root.partial" "$root"  # whole or not at all
    ;;
run)
    [ $# -ge 1 ] || usage
    exec unshare --mount --fork sh -c 'mount -t proc proc "$0/proc" && exec chroot "$0" "$@"' "$root" "$@"
    ;;
*)
    usage
    ;;
esac
