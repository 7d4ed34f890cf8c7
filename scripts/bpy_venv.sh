#!/usr/bin/env bash
# Prints the python of a venv (.venv-bpy-VERSION, ignored by git) that has requirements-dev.txt
# with bpy pinned to VERSION; creates or refreshes it first when needed. Used by the version
# matrix (scripts/test_matrix.sh) and by the install test on the other Blender versions.
set -euo pipefail
version=$1
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
venv="$root/.venv-bpy-$version"
requirements="$venv.requirements.txt"
sed "s/^bpy==.*/bpy==$version/" "$root/requirements-dev.txt" > "$requirements.new"
if [ ! -x "$venv/bin/python" ] || ! cmp -s "$requirements.new" "$requirements"; then
  rm -rf "$venv"
  python3.11 -m venv "$venv" >&2
  "$venv/bin/python" -m pip install -q -r "$requirements.new" >&2
  mv "$requirements.new" "$requirements"
else
  rm -f "$requirements.new"
fi
echo "$venv/bin/python"
