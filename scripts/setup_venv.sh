#!/usr/bin/env bash
# Creates ./.venv (ignored by git) with the pinned dependencies of requirements-dev.txt, and the
# Debian libraries that the bpy module loads (X11/GL client libraries, Mesa's software renderer
# for the headless GPU tests). Idempotent: when everything is in place it only checks, in ~1 s.
# A changed requirements-dev.txt is installed into the existing venv (pip installs only what is
# missing or pinned at another version): adding a pin never rebuilds the venv and its 370 MB bpy.
# The venv is created only when its Python is missing.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
venv="$root/.venv"
# The hash of the requirements last installed by this script. (.requirements.sha256 was the
# stamp of earlier versions, which rebuilt the venv when it differed: it is read, never written,
# so that a venv shared with an older checkout is never rebuilt by that checkout.)
stamp="$venv/.requirements-installed.sha256"
legacy_stamp="$venv/.requirements.sha256"
want=$(sha256sum "$root/requirements-dev.txt" | cut -d' ' -f1)

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else return 1; fi; }

apt_install() {
  command -v apt-get >/dev/null || { echo "setup: please install the Debian packages: $*" >&2; return 1; }
  echo "setup: installing Debian packages: $*"
  as_root apt-get update -qq && as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$@" >/dev/null
}

# bpy wheels exist for CPython 3.11 only (Blender 4.2 to 5.0).
python=${PYTHON:-}
if [ -z "$python" ]; then
  for candidate in python3.11 python3; do
    if command -v "$candidate" >/dev/null && "$candidate" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
      python=$candidate; break
    fi
  done
fi
[ -n "$python" ] || { echo "setup: Python 3.11 is required (the bpy module is built for CPython 3.11)" >&2; exit 1; }

system_packages=(libgl1 libglx0 libegl1 libegl-mesa0 libgl1-mesa-dri libx11-6 libxext6 libxfixes3
  libxi6 libxrender1 libxkbcommon0 libsm6 libice6 libxxf86vm1)
if command -v dpkg-query >/dev/null; then
  missing=()
  for pkg in "${system_packages[@]}"; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
  done
  [ ${#missing[@]} -eq 0 ] || apt_install "${missing[@]}"
fi

if [ ! -x "$venv/bin/python" ]; then
  if ! "$python" -m venv --help >/dev/null 2>&1 || ! "$python" -c 'import ensurepip' 2>/dev/null; then
    apt_install python3-venv
  fi
  "$python" -m venv "$venv"
  "$venv/bin/python" -m pip install -q --upgrade pip
fi
installed=$(cat "$stamp" 2>/dev/null || cat "$legacy_stamp" 2>/dev/null || true)
if [ "$installed" != "$want" ]; then
  echo "setup: installing requirements-dev.txt into $venv (only what is missing or at another version)"
  "$venv/bin/python" -m pip install -q -r "$root/requirements-dev.txt"
  echo "$want" > "$stamp"
fi
