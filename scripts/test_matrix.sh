#!/usr/bin/env bash
# Runs the tests on several Blender versions, each in its own venv (.venv-bpy-X.Y.Z, ignored by
# git) that differs from requirements-dev.txt only in the bpy pin.
#   bash scripts/test_matrix.sh                 # whole suite on every version
#   bash scripts/test_matrix.sh -m blender      # extra arguments go to pytest
# BPY_VERSIONS overrides the list (space separated).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
versions=${BPY_VERSIONS:-"4.2.23 4.5.15 5.0.1"}
bash "$root/scripts/setup_venv.sh"   # system libraries and the default venv
status=0
for version in $versions; do
  venv="$root/.venv-bpy-$version"
  requirements="$venv.requirements.txt"
  sed "s/^bpy==.*/bpy==$version/" "$root/requirements-dev.txt" > "$requirements.new"
  if [ ! -x "$venv/bin/python" ] || ! cmp -s "$requirements.new" "$requirements"; then
    rm -rf "$venv"
    python3.11 -m venv "$venv"
    "$venv/bin/python" -m pip install -q -r "$requirements.new"
    mv "$requirements.new" "$requirements"
  else
    rm -f "$requirements.new"
  fi
  echo "=== bpy $version"
  (cd "$root" && "$venv/bin/python" -m pytest "$@") || status=1
done
exit $status
